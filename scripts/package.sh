#!/usr/bin/env bash
# Build the zip a user installs with QGIS's "Plugins > Manage and Install Plugins > Install from ZIP":
# one folder pushbroom_adjust/ holding the plugin only (no tests, benches, scripts or CI files).
# Files come from git: the tracked files as they are now (uncommitted edits to them included, said on
# stderr), so untracked files never slip in.
# Usage: bash scripts/package.sh [OUTPUT_FOLDER]   (default dist/); prints the zip's path,
# OUTPUT_FOLDER/pushbroom_adjust-<version of metadata.txt>.zip.
set -euo pipefail
cd "$(dirname "$0")/.."

PLUGIN=pushbroom_adjust
CONTENT=(metadata.txt __init__.py plugin.py LICENSE README.md docs core simulation ui resources)

version="$(sed -n 's/^version=//p' metadata.txt | tr -d '\r')"
if ! [[ "$version" =~ ^[0-9]+(\.[0-9]+)*[A-Za-z0-9.+-]*$ ]]; then
    echo "package: metadata.txt has no usable version= line (found '$version')" >&2
    exit 1
fi
if ! git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
    echo "package: $PWD is not a git checkout; the package is built from git's list of tracked files" >&2
    exit 1
fi
for item in "${CONTENT[@]}"; do
    if ! git ls-files --error-unmatch -- "$item" >/dev/null 2>&1; then
        echo "package: $item is not tracked by git (git add it, or it cannot go into the package)" >&2
        exit 1
    fi
done
# A commit of the tracked files as they are in the work tree (empty when nothing is changed); no ref
# or file is touched.
tree="$(git stash create)"
if [ -n "$tree" ]; then
    echo "package: including uncommitted changes to tracked files" >&2
fi

out_dir="${1:-dist}"
mkdir -p "$out_dir"
zip="$out_dir/$PLUGIN-$version.zip"
part="$(mktemp -p "$out_dir" ".$PLUGIN-$version.XXXXXX")"
trap 'rm -f "$part"' EXIT
git archive --format=zip --prefix="$PLUGIN/" -o "$part" "${tree:-HEAD}" -- "${CONTENT[@]}"
chmod "$(printf '%o' $((0666 & ~0$(umask))))" "$part"  # mktemp makes it 0600: follow the umask instead
mv -f "$part" "$zip"
trap - EXIT
echo "$zip"

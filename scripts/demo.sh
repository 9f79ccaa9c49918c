#!/usr/bin/env bash
# The main job on the command line, without a manual point: simulate the default CBERS-02B HRC
# scene with its raw image and a reference orthoimage, match GCPs between the two, adjust the
# onboard model to them (calibrating the CCDs), orthorectify the raw image with the adjusted model,
# make the sensor-corrected image (the CCDs resampled onto one straight virtual detector line) with
# its RPC, trace the footprint and project the GCPs into the image, all through qgis_process, into
# ./out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh

OUT="$PWD/out"
mkdir -p "$OUT/logs"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
# QGIS finds plugins by folder name: show it this checkout as 'pushbroom_adjust', in a private profile.
mkdir -p "$WORK/plugins" "$WORK/profile" "$WORK/runtime"
ln -s "$PWD" "$WORK/plugins/pushbroom_adjust"
export QGIS_PLUGINPATH="$WORK/plugins" QGIS_CUSTOM_CONFIG_PATH="$WORK/profile" QT_QPA_PLATFORM=offscreen
export XDG_RUNTIME_DIR="$WORK/runtime"
QGIS_PROCESS=/usr/bin/qgis_process.bin  # Debian's qgis_process wrapper script is broken; the binary works

"$QGIS_PROCESS" plugins enable pushbroom_adjust >"$OUT/logs/plugins.log" 2>&1 </dev/null

run() {  # run ALGORITHM PARAM=VALUE... ; full log in out/logs/ALGORITHM.log
    local alg="$1"; shift
    echo "== pushbroom:$alg"
    if ! "$QGIS_PROCESS" run "pushbroom:$alg" -- "$@" >"$OUT/logs/$alg.log" 2>&1 </dev/null; then
        cat "$OUT/logs/$alg.log"
        echo "demo: pushbroom:$alg failed (log: out/logs/$alg.log)" >&2
        exit 1
    fi
    # qgis_process prints its progress dots before an algorithm's first line: strip them
    sed -E 's/^[.0-9]*\.\.//' "$OUT/logs/$alg.log" |
        grep -E "^(WARNING|[a-z].*residuals|[0-9]+ points|sigma0|check points|orthoimage|written in|check on|  CCD|matched|rejected|onboard offset|sensor-corrected image|RPC fitted)" || true
}

SIM="$OUT/simulation"
run simulatescene SEED=0 N_GCPS=20 RENDER=true OUTPUT_FOLDER="$SIM"
run matchgcps INPUT="$SIM/image_HRC.tif" SCENE="$SIM/onboard_scene.json" REFERENCE="$SIM/reference.tif" \
    DEM="$SIM/dem.tif" DEM_DATUM=geoid SPACING=200 CHECK_FRACTION=0.2 OUTPUT="$OUT/gcps.gpkg"
# The simulated reference and DEM are exact (the reference's pixels lie where its geotransform says, the
# DEM is the terrain the scene was rendered on): the matched GCPs' ground is held fixed, and their
# image sigmas (the matching's own precision) are all the adjustment weighs.
run bundleadjust SCENE="$SIM/onboard_scene.json" GCPS="$OUT/gcps.gpkg" INTERIOR="HRC-1.*, HRC-3.*" POSITION_ORDER=0 \
    GROUND=fixed OUTPUT_SCENE="$OUT/adjusted_scene.json" OUTPUT_REPORT="$OUT/adjustment.html" \
    OUTPUT_GCPS="$OUT/adjusted_gcps.gpkg" OUTPUT_RESIDUALS="$OUT/residuals.gpkg"
run orthorectify INPUT="$SIM/image_HRC.tif" SCENE="$OUT/adjusted_scene.json" DEM="$SIM/dem.tif" DEM_DATUM=geoid \
    OUTPUT="$OUT/orthoimage.tif"
# One RPC cannot follow the steps of the three separately aligned CCDs (about 1 px RMS, 3 px at a seam):
# the sensor-corrected image, one straight virtual detector line through the adjusted model, has an RPC
# that fits its model to a ten-thousandth of a pixel.
run sensorcorrect INPUT="$SIM/image_HRC.tif" SCENE="$OUT/adjusted_scene.json" DEM="$SIM/dem.tif" DEM_DATUM=geoid \
    OUTPUT="$OUT/HRC_corrected.tif" OUTPUT_SCENE="$OUT/HRC_corrected_scene.json"
run footprint SCENE="$OUT/adjusted_scene.json" DEM="$SIM/dem.tif" DEM_DATUM=geoid OUTPUT="$OUT/footprint.gpkg"
run groundtoimage SCENE="$OUT/adjusted_scene.json" INPUT="$OUT/gcps.gpkg" OUTPUT="$OUT/gcps_in_image.gpkg"

cat <<END

Results in $OUT:
  simulation/         simulated scene: onboard_scene.json, true_scene.json, dem.tif, simulation.json,
                      image_HRC.tif (the raw 12246 x 12246 image), reference.tif (the reference orthoimage)
  gcps.gpkg           the GCPs matched between the raw image and the reference (quality, peak_ratio, sigma_px;
                      a fifth of them check points; a-priori residuals res_col, res_row, res_m)
  adjusted_scene.json the adjusted scene (any algorithm's SCENE); adjustment.html / .json its report
  adjusted_gcps.gpkg  the GCPs with adjusted residuals and gross-error flags; residuals.gpkg as vectors
  orthoimage.tif      the raw image orthorectified with the adjusted model (UTM, 2.36 m, overviews)
  HRC_corrected.tif   the sensor-corrected image: the three CCDs resampled through the adjusted model onto one
                      straight virtual detector line; HRC_corrected_scene.json its scene (any algorithm's SCENE)
  HRC_corrected_RPC.TXT its RPC00B (fit report in HRC_corrected_RPC.TXT.json); HRC_corrected.vrt the image
                      with that RPC: gdalwarp -rpc or QGIS's Warp can use either
  footprint.gpkg      ground outline of the adjusted scene (open in QGIS over the DEM)
  gcps_in_image.gpkg  the GCPs projected into the image by the adjusted model (fields col_2, row_2)
  logs/               full qgis_process output of each step
END

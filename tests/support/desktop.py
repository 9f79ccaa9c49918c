"""The real QGIS desktop, driven from a test or a script: the ``qgis`` binary under a virtual X
server (xvfb-run; QGIS refuses to start without a display, and crashes on Qt's offscreen platform)
with a fresh profile in which the plugin is enabled, running a driver script inside QGIS
(``qgis --code``). The driver reads its arguments with :func:`driver_arguments`, writes what it saw
with :func:`write_result` and quits QGIS; :func:`run_desktop` returns that and QGIS's stderr.

The profile disables the GRASS and SAGA providers, which are not installed here: their start-up
CRITICAL lines ('GRASS was not found') are no part of this plugin. QGIS's own Python start-up
prints one DeprecationWarning ('setapi() is deprecated') before any plugin loads; that one message,
and only it, is filtered out of stderr by a Python warnings filter.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import traceback
from pathlib import Path

from tests.support.paths import PLUGIN, REPO

QGIS = "/usr/bin/qgis"
SCREEN = "1600x1000x24"
ARGS_ENV = "PUSHBROOM_DESKTOP_ARGS"
QGIS_OWN_WARNING = "ignore:setapi() is deprecated:DeprecationWarning"


def make_profile(folder: Path) -> Path:
    """A profiles folder for ``qgis --profiles-path``: profile 'default' with the plugin (a link
    to the repository) enabled, GRASS and SAGA disabled."""
    profile = folder / "profiles" / "default"
    (profile / "python" / "plugins").mkdir(parents=True, exist_ok=True)
    link = profile / "python" / "plugins" / PLUGIN
    if not link.exists():
        link.symlink_to(REPO, target_is_directory=True)
    (profile / "QGIS").mkdir(exist_ok=True)
    (profile / "QGIS" / "QGIS3.ini").write_text(f"[PythonPlugins]\n{PLUGIN}=true\ngrassprovider=false\n"
                                                "sagaprovider=false\n")
    return folder


def run_desktop(driver: Path, arguments: dict, folder: Path, timeout: float = 600) -> tuple[dict, str]:
    """Start QGIS with a fresh profile in ``folder``, run ``driver`` (a Python file) inside it with
    ``arguments`` (JSON; the key 'result' is added: where the driver writes what it saw), wait
    until QGIS exits; (the driver's result, QGIS's stderr). AssertionError with stderr when QGIS
    fails or writes no result."""
    assert shutil.which("xvfb-run"), "xvfb-run not found: bash scripts/setup.sh installs it (Debian's xvfb, xauth)"
    folder.mkdir(parents=True, exist_ok=True)
    make_profile(folder)
    result = folder / "result.json"
    result.unlink(missing_ok=True)
    args = folder / "arguments.json"
    args.write_text(json.dumps({**arguments, "result": str(result)}))
    runtime = Path(tempfile.mkdtemp(prefix="xdg-", dir=folder))
    runtime.chmod(0o700)
    env = dict(os.environ, **{ARGS_ENV: str(args)}, XDG_RUNTIME_DIR=str(runtime), PYTHONWARNINGS=QGIS_OWN_WARNING,
               PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    for name in ("QT_QPA_PLATFORM", "QGIS_CUSTOM_CONFIG_PATH", "DISPLAY"):
        env.pop(name, None)  # the virtual display, and the profile given here
    # a session of its own: on a timeout QGIS and the X server go with xvfb-run, not only xvfb-run
    run = subprocess.Popen(["xvfb-run", "-a", "-s", f"-screen 0 {SCREEN}", QGIS, "--nologo", "--noversioncheck",
                            "--profiles-path", str(folder), "--code", str(driver)], env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL, start_new_session=True)
    try:
        stdout, stderr = run.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(run.pid, signal.SIGKILL)
        stdout, stderr = run.communicate()
        raise AssertionError(f"QGIS did not quit within {timeout} s; stderr:\n{stderr}") from None
    (folder / "qgis_stdout.txt").write_text(stdout)  # QGIS's own trace of a crash goes there
    assert result.is_file(), f"QGIS exited {run.returncode} without a result; stderr:\n{stderr}"
    return json.loads(result.read_text()), stderr


def driver_arguments() -> dict:
    """Inside QGIS: the arguments :func:`run_desktop` gave the driver."""
    return json.loads(Path(os.environ[ARGS_ENV]).read_text())


def record_exceptions(exceptions: list) -> None:
    """Inside QGIS: Python exceptions (also those raised in Qt slots) appended to ``exceptions`` as
    text, instead of QGIS's modal dialog, which would leave the run waiting for a click."""
    import qgis.utils

    def keep(kind, value, tb):
        exceptions.append("".join(traceback.format_exception(kind, value, tb)))

    sys.excepthook = qgis.utils.qgis_excepthook = keep


def quit_qgis() -> None:
    """Inside QGIS: leave. The project is cleared first: QGIS 3.22 left with layers in its project
    crashes in its own teardown (the layer styling panel, gone, told of the current layer's removal)."""
    from qgis.core import QgsApplication, QgsProject
    QgsProject.instance().clear()
    QgsApplication.processEvents()
    QgsApplication.exit(0)


def write_result(arguments: dict, result: dict) -> None:
    Path(arguments["result"]).write_text(json.dumps(result, indent=1, default=str))

"""One small simulated three-line scene (TH-1, cut to 600 x 600 px, rendered, noise-free measurements)
for the tests of the import and matching use cases, made once by simulation.runs.run_scene."""
import pytest

from pushbroom_adjust.simulation import runs
from pushbroom_adjust.simulation.measurements import GcpSettings
from pushbroom_adjust.simulation.roads import RoadSettings

N_GCPS, N_TIE_POINTS, N_LINES = 30, 40, 3


@pytest.fixture(scope="session")
def th1(tmp_path_factory) -> dict:
    """The files of the simulation (simulation.runs' names: ONBOARD_SCENE, TRUE_SCENE, GCPS, ...)."""
    folder = tmp_path_factory.mktemp("runs_th1") / "sim"
    return runs.run_scene(runs.SimulateSceneRequest(
        str(folder), "th1_tlc", seed=1, render=True, gcps=GcpSettings(n_gcps=N_GCPS, image_noise=0.0,
                                                                      n_tie_points=N_TIE_POINTS),
        roads=RoadSettings(n_lines=N_LINES), image_size=600)).files

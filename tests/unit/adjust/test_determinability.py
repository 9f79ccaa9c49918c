"""core.adjust.determinability.non_determinable on normal matrices the fuzzing produced: overflowed
weights (a sigma of 1e-300) gave a LinAlgError traceback; now an InputError naming the parameters.
Plausible onboard sigmas are checked with the settings."""
import numpy as np
import pytest

from pushbroom_adjust.core.adjust.determinability import non_determinable
from pushbroom_adjust.core.adjust.settings import AdjustmentSettings
from pushbroom_adjust.core.errors import InputError

NAMES = ["position.X.bias", "position.Y.bias", "attitude.roll.bias", "HRC.f"]
TRAJECTORY = np.array([True, True, True, False])


def _normal(scale=np.ones(4)) -> np.ndarray:
    """A well-conditioned 4 x 4 normal matrix, its parameters scaled by ``scale``."""
    a = np.random.default_rng(1).normal(size=(20, 4))
    return (a.T @ a) * np.outer(scale, scale)


def test_a_determinable_block_has_no_sets_whatever_its_units():
    """Diagonals from 1e-200 to 1e100 (the parameters' units): scaled one side at a time, nothing
    underflows or overflows."""
    assert non_determinable(_normal(), NAMES, TRAJECTORY) == []
    assert non_determinable(_normal(np.array([1e-100, 1.0, 1e50, 1e-60])), NAMES, TRAJECTORY) == []


def test_a_trajectory_pair_that_moves_together_is_named():
    N = _normal()
    N[:, 1], N[1, :] = N[:, 0], N[0, :]  # position.Y.bias acts exactly as position.X.bias
    sets = non_determinable(N, NAMES, TRAJECTORY)
    assert len(sets) == 1 and set(sets[0][:2]) == {"position.X.bias", "position.Y.bias"}


@pytest.mark.parametrize("bad", [np.inf, np.nan, -np.inf])
def test_overflowed_normal_equations_are_named_not_a_linalg_error(bad):
    N = _normal()
    N[3, 3] = bad
    N[0, 3] = N[3, 0] = bad
    with pytest.raises(InputError, match=r"the normal equations of position.X.bias, HRC.f are not finite numbers: "
                                         r"a weight overflowed") as info:
        non_determinable(N, NAMES, TRAJECTORY)
    assert info.value.parameter == ""


@pytest.mark.parametrize("settings, name", [
    (AdjustmentSettings(position_sigma=1e-300), "position_sigma"),
    (AdjustmentSettings(position_sigma=1e300), "position_sigma"),
    (AdjustmentSettings(attitude_sigma=1e-300), "attitude_sigma"),
    (AdjustmentSettings(attitude_sigma=10.0), "attitude_sigma"),
])
def test_onboard_sigmas_beyond_any_gnss_or_star_tracker_are_refused(settings, name):
    with pytest.raises(InputError, match=rf"{name.upper()} must be empty \(no pseudo-observations\) or between") as info:
        settings.validate()
    assert info.value.parameter == f"settings.{name}"


def test_plausible_onboard_sigmas_pass():
    AdjustmentSettings(position_sigma=0.05, attitude_sigma=1e-6).validate()
    AdjustmentSettings(position_sigma=None, attitude_sigma=None).validate()

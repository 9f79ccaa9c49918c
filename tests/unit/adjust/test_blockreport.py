"""A block's own report (core/adjust/blockreport.py): the scenes no control point holds that moved
beyond DRIFT_SIGMAS times their stated accuracy are named, and the block report reads as its JSON
(its own warnings first, then its adjustment's) and says its figures in the log."""
from pushbroom_adjust.core.adjust.blockreport import DRIFT_SIGMAS, beyond_stated
from pushbroom_adjust.core.adjust.report_types import BlockReport
from tests.unit.adjust.test_report_types import report


def test_the_block_report_reads_as_its_json():
    scene = {"cameras": ["NAD"], "control": {"observations": 0, "rmse_px": None},
             "check_points": {"observations": 4, "rmse_px": 0.5}, "model": "rigorous", "moved_m": 70.0,
             "onboard_sigma_m": 20.0, "sigmas": {"position_sigma_m": 20.0, "attitude_sigma_arcsec": None,
                                                 "own": ["position_sigma"]}}
    moved = beyond_stated({"A": scene}, controlled=False)
    assert len(moved) == 1 and moved[0].startswith("scene A moved 70 m") and "3.5 times" in moved[0]
    assert 70.0 > DRIFT_SIGMAS * 20.0 and beyond_stated({"A": scene}, controlled=True) == []
    limit = report(robust={"passes": [1], "stopped_at_limit": True, "flagged": 0})
    block = BlockReport({"scenes": 1, "sigma0": 1.0, "tie_rmse_px": None, "tie_rmse_before_px": None},
                        {"A": scene}, moved, limit)
    assert list(block) == ["block", "scenes", "datum", "datum_directions", "warnings", "written_vs_fitted",
                           "adjustment"]
    assert block["warnings"] == moved + limit.warnings and block.own_warnings() == moved
    assert block.as_dict()["adjustment"] == limit.as_dict() and block["written_vs_fitted"] == {"max_px": 0.0}
    said = block.log_lines()
    assert said[0].text == ("scene A: no control points, check 0.500 px (4 obs.); moved 70.0 m from its "
                                   "onboard geolocation (onboard sigma 20.0 m; stated 20 m (own), - arcsec)")
    assert [line.warning for line in said] == [False, False, True]

"""Self-calibrating bundle adjustment of one scene (or strip) from ground control points and
tie points (ground points of unknown position, :mod:`core.adjust.ties`).

Gauss-Newton with Levenberg-Marquardt damping on the reduced normal equations (ground
points eliminated, :mod:`core.adjust.normal`), analytic derivatives (:mod:`core.adjust.model`).
Onboard GPS and star-tracker values enter as pseudo-observations of the trajectory
corrections at the knots (seed 000 eq. 7-8); weighted interior parameters as
pseudo-observations of value 0. Before solving, the parameters are checked for
determinability: sets that the observations cannot separate (seed 000 Table II schemes 1-2)
are named, and one parameter of each set is fixed (or the run stops, as the settings say).
Gross errors: selection-weight iteration from posterior variances (Li Deren), or iterated
Baarda data snooping; either way, observations whose normalised residual w exceeds the
critical value at the end are flagged (never deleted from the input).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import InputError, NoDescentError
from ..model.mixedblock import MixedBlock
from ..model.rpcscene import RpcScene
from ..model.sensor import SceneModel
from ..observations.gcps import GcpTable
from ..observations.tiepoints import TieTable
from .blockproblem import BlockProblem
from .checks import block_datum, check_inputs, check_redundancy
from .consistency import check_written_scene
from .determinability import check_determinability
from .estimation import estimate
from .linepoints import ControlLines, LineSetUp, set_up_lines
from .minimalprior import hold_weak_trajectory
from .problem import Problem
from .report_types import StageOutcomes
from .results import AdjustmentResult, result_of
from .rpcbias import RpcProblem
from .selection import conventional_instead, interior_free, select_interior
from .settings import AdjustmentSettings
from .tieheights import reference_of
from .ties import TieSetUp, set_up_ties

log = logging.getLogger(__name__)


@dataclass
class _ProblemOf:
    """The engine's problem of each kind of scene (asked through ``scene.answer``,
    :mod:`core.model.kinds`): of a rigorous scene, of an RPC scene (its image-space correction,
    :mod:`core.adjust.rpcbias`), of a block with RPC images (:mod:`core.adjust.blockproblem`)."""
    table: GcpTable
    settings: AdjustmentSettings
    ties: TieSetUp
    lines: LineSetUp | None = None

    def rigorous(self, scene: SceneModel) -> Problem:
        return Problem(scene, self.table, self.settings, self.ties, self.lines)

    def rpc(self, scene: RpcScene) -> RpcProblem:
        if len(self.ties):
            raise InputError("tie points need a rigorous (physical) scene model with several cameras; an RPC "
                             "scene is one image", parameter="ties")
        return RpcProblem(scene, self.table, self.settings)

    def block(self, scene: MixedBlock) -> BlockProblem:
        if len(self.lines or ()):
            raise InputError("control lines need rigorous (physical) scene models; a block with RPC images is "
                             "adjusted from GCPs and tie points", parameter="lines")
        return BlockProblem(scene, self.table, self.settings, self.ties)


def adjust(scene: SceneModel, table: GcpTable, settings: AdjustmentSettings | None = None,
           progress: Callable[[float, str | None], None] | None = None,
           is_cancelled: Callable[[], bool] | None = None, ties: TieTable | None = None,
           lines: ControlLines | None = None,
           tie_rays: tuple[np.ndarray, np.ndarray] | None = None) -> AdjustmentResult:
    """Adjust ``scene`` to the control points of ``table``, the tie points ``ties`` and the
    control lines ``lines`` (both optional); evaluate its check points. With tie points the
    control may be sparse or absent when the onboard pseudo-observations hold the datum
    (report["datum"] says how it is held); with lines too (report["lines"]["directions"] says
    whether they determine both horizontal directions). ``tie_rays``: the tie observations' onboard
    rays (:func:`core.model.intersection.onboard_rays`) when the caller has them."""
    settings = settings or AdjustmentSettings()
    return adjust_checked(scene, check_inputs(scene, table, settings, ties, lines), settings, progress, is_cancelled,
                          ties, lines, tie_rays)


def adjust_checked(scene: SceneModel, table: GcpTable, settings: AdjustmentSettings,
                   progress: Callable[[float, str | None], None] | None = None,
                   is_cancelled: Callable[[], bool] | None = None, ties: TieTable | None = None,
                   lines: ControlLines | None = None,
                   tie_rays: tuple[np.ndarray, np.ndarray] | None = None) -> AdjustmentResult:
    """:func:`adjust` of inputs :func:`core.adjust.checks.check_inputs` has checked (``table``: the
    table it returned), for a caller that checks them before its own work (outputs planned, files
    read), so that nothing is checked twice."""
    progress = progress or (lambda fraction, message=None: None)
    is_cancelled = is_cancelled or (lambda: False)
    held = block_datum(table, settings, ties, lines, scene)
    progress(0.02, "setting up the observations")
    if settings.tie_height_sigma is not None and (ties is None or not len(ties)):
        raise InputError("TIE_HEIGHT_SIGMA holds the tie points' heights to the reference DEM: give TIE_POINTS",
                         parameter="settings.tie_height_sigma")
    tie_set = set_up_ties(scene, ties, reference_of(settings.dem, settings.dem_datum, settings.tie_height_sigma),
                          tie_rays) if ties is not None and len(ties) else TieSetUp.empty()
    problem = scene.answer(_ProblemOf(table, settings, tie_set, set_up_lines(scene, lines)))
    if problem.rpc_choice is not None:
        log.info("%s", problem.rpc_choice["sentence"])
    check_redundancy(problem)
    lin, system = problem.system()
    determinability = check_determinability(problem, system)
    trajectory_prior = hold_weak_trajectory(problem, problem.system()[1] if determinability else system)
    # the first solution starts from these normal equations when neither check changed the problem (at a
    # thousand RPC products one assembly costs 12 s)
    start = (lin, system) if not determinability and trajectory_prior is None else None
    selection = None
    selecting = settings.interior_selection == "significant" and interior_free(problem).size > 0
    if selecting and system.is_sparse:
        log.warning("interior parameters are not selected by significance on a block of %d unknowns (the tests need "
                    "the full covariance, %d^2 numbers): every free interior parameter is kept",
                    system.N.shape[0], system.N.shape[0])
        selecting = False
    try:
        est = estimate(problem, progress, is_cancelled, start)
    except NoDescentError as err:
        if not selecting:
            raise
        problem, est, selection = conventional_instead(problem, lambda p: estimate(p, progress, is_cancelled),
                                                       f"the self-calibrating solution did not converge: {err}")
    else:
        if selecting:
            problem, est, selection = select_interior(problem, est, lambda p: estimate(p, progress, is_cancelled))
    if est.at_limit:  # said of the reported solution only, not of the interior selection's trial solutions
        log.warning("robust estimation stopped at its limit of %d passes; the flags may be incomplete",
                    len(est.passes))
    progress(0.92, "evaluating check points")
    adjusted = problem.params.adjusted_scene()
    stages = StageOutcomes(determinability, selection, problem.rpc_choice, trajectory_prior,
                           check_written_scene(problem, adjusted), held)
    return result_of(problem, table, adjusted, est, stages)

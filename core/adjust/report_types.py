"""The adjustment's report as types: :class:`AdjustmentReport` (one adjustment, a scene or a
block's composite) and :class:`BlockReport` (a block's own figures around its adjustment's
report), each built once after the solution and never changed after.

Both read as their JSON (a read-only mapping over the JSON keys, :meth:`AdjustmentReport.as_dict`),
which :func:`core.adjust.report.write_report_json` writes, :mod:`core.adjust.report_html` renders
for people and :func:`core.adjust.report.log_lines` (:meth:`BlockReport.log_lines`) says in the log.
Sections are JSON-ready dicts and lists as the stage that computed them returned them; their keys
are documented where they are computed (:func:`core.adjust.results.result_of`,
:func:`core.adjust.blockreport.block_report`).
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, fields
from functools import cached_property

from ..log import LogLine
from .report import datum_sentence, report_warnings
from .scenesigmas import sigmas_text

OMITTED_WHEN_NONE = ("tie_points", "lines", "datum")
"""Sections absent from the JSON (not null) when a run has none: no tie points, no control lines,
no tie points to hold the datum."""


@dataclass(frozen=True)
class StageOutcomes:
    """What the stages around the solution return for the report: determinability (the parameter
    sets fixed as not determinable, :func:`core.adjust.determinability.check_determinability`);
    interior_selection (:mod:`core.adjust.selection`, None without INTERIOR_SELECTION=significant);
    rpc_correction (the RPC correction chosen by default, None for rigorous scenes);
    trajectory_prior (:func:`core.adjust.minimalprior.hold_weak_trajectory`); written_vs_fitted
    (:func:`core.adjust.consistency.check_written_scene`); held (how the datum is held before the
    solution, :func:`core.adjust.checks.block_datum`; None without tie points)."""
    determinability: list
    interior_selection: dict | None
    rpc_correction: dict | None
    trajectory_prior: dict | None
    written_vs_fitted: dict | None
    held: dict | None


class _JsonView(Mapping):
    """A report read as its JSON: the keys :meth:`json_keys` names, each the attribute of that name."""

    def json_keys(self) -> list[str]:
        raise NotImplementedError

    def __getitem__(self, key: str):
        if key not in self.json_keys():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(self.json_keys())

    def __len__(self) -> int:
        return len(self.json_keys())

    def as_dict(self) -> dict:
        """The report as the dict its JSON file holds (nested reports as dicts too; numbers as
        computed: :func:`core.adjust.report.plain` makes them strict JSON)."""
        return {k: v.as_dict() if isinstance(v, _JsonView) else v for k, v in self.items()}


@dataclass(frozen=True, eq=False)
class AdjustmentReport(_JsonView):
    """One adjustment's figures, in the order of its JSON. From the solution
    (:func:`core.adjust.results.result_of`): settings (the :class:`AdjustmentSettings` as a dict),
    observations (counts), iterations, robust (method, passes, critical w, flags), reliability,
    sigma0 (of the stated sigmas), sigma0_adjusted, sigma0_test, variance_components,
    determinability, parameters (each name, block, value, sigma, unit, mode, significant),
    high_correlations, control_residuals, control_ground (None with fixed ground),
    control_residuals_per_chip, check_points and check_points_before, trajectory (correction
    curves; None without trajectory unknowns), tie_points and lines (None: absent from the JSON);
    from the stages (:class:`StageOutcomes`): interior_selection, rpc_correction,
    trajectory_prior, written_vs_fitted, and datum (how it is held, with the yaw's posterior sigma
    and the datum directions; None without tie points: absent from the JSON). ``warnings`` (the
    JSON's last key) follows from robust, reliability and datum (:func:`core.adjust.report.
    report_warnings`)."""
    settings: dict
    observations: dict
    iterations: list
    robust: dict
    reliability: dict
    sigma0: float | None
    sigma0_adjusted: float | None
    sigma0_test: dict
    variance_components: dict
    determinability: list
    parameters: list
    high_correlations: list
    control_residuals: dict
    control_ground: dict | None
    control_residuals_per_chip: dict
    check_points: dict
    check_points_before: dict
    trajectory: dict | None
    tie_points: dict | None
    lines: dict | None
    interior_selection: dict | None
    rpc_correction: dict | None
    trajectory_prior: dict | None
    written_vs_fitted: dict | None
    datum: dict | None

    def json_keys(self) -> list[str]:
        return [f.name for f in fields(self) if f.name not in OMITTED_WHEN_NONE or getattr(self, f.name) is not None] \
            + ["warnings"]

    @cached_property
    def warnings(self) -> list[str]:
        """The run's warnings (:func:`core.adjust.report.report_warnings`)."""
        return report_warnings(self)

    def scene_record(self) -> dict:
        """What the adjusted scene carries of its adjustment (its ``info["adjustment"]``): settings,
        sigma0, variance components, reliability, the parameters that are not fixed at 0,
        determinability, interior selection, check-point figures, and with tie points the datum and
        the number of tie points, with lines their figures."""
        record = {
            "settings": self.settings, "sigma0": self.sigma0,
            "variance_components": {k: {f: v[f] for f in ("apriori_sigma", "estimated_sigma", "unit", "estimated")}
                                    for k, v in self.variance_components.items()},
            "reliable": self.reliability["reliable"], "robust_stopped_at_limit": self.robust["stopped_at_limit"],
            "parameters": [{k: p[k] for k in ("name", "value", "sigma", "unit", "mode")}
                           for p in self.parameters if p["mode"] != "fixed" or p["value"] != 0.0],
            "determinability": self.determinability, "interior_selection": self.interior_selection,
            "check_points": {k: self.check_points.get(k) for k in ("points", "image", "ground")}}
        if self.datum is not None:
            record["datum"] = {k: self.datum[k] for k in ("held_by", "control_points", "control_lines", "note", "yaw",
                                                          "directions") if k in self.datum}
            record["tie_points"] = self.observations["tie_points"]["points"]
        if self.lines is not None:
            record["lines"] = {k: self.lines[k] for k in ("lines", "points", "flagged_line_ids", "across_rmse_m",
                                                          "directions")}
        return record


def px_text(value: float | None) -> str:
    """'0.123 px', or '-' for a figure that could not be computed."""
    return "-" if value is None else f"{value:.3f} px"


def metres_text(value: float | None) -> str:
    """'12.3 m RMS', or '-' for a figure that could not be computed."""
    return "-" if value is None else f"{value:.1f} m RMS"


@dataclass(frozen=True, eq=False)
class BlockReport(_JsonView):
    """A block adjustment's own figures (:func:`core.adjust.blockreport.block_report`) around its
    adjustment's report: block (the block's control, check and tie RMS, px; sigma0; lines; accuracy,
    :func:`core.adjust.report_accuracy.absolute_accuracy`), scenes
    (per scene: cameras, control, check and tie figures, the move from its input geolocation, the
    sigmas it was adjusted with, its lines), scene_warnings (scenes held by no control point that
    moved beyond their stated accuracy), adjustment (the composite's :class:`AdjustmentReport`).
    Its JSON: block, scenes, datum (the sentence), datum_directions, warnings (the block's own,
    then the adjustment's), written_vs_fitted, adjustment."""
    block: dict
    scenes: dict
    scene_warnings: list
    adjustment: AdjustmentReport

    def json_keys(self) -> list[str]:
        return ["block", "scenes", "datum", "datum_directions", "warnings", "written_vs_fitted", "adjustment"]

    @property
    def datum(self) -> str:
        """How the block's datum is held, in one sentence (:func:`core.adjust.report.datum_sentence`)."""
        return datum_sentence(self.adjustment, "the ")

    @property
    def datum_directions(self) -> list:
        """The moves of the whole block the tie points leave to the priors or hardly determine
        (:mod:`core.adjust.datumdirections`); empty without tie points."""
        return (self.adjustment.datum or {}).get("directions", [])

    @property
    def warnings(self) -> list[str]:
        """The block's own warnings, then its adjustment's."""
        return [*self.scene_warnings, *self.adjustment.warnings]

    @property
    def written_vs_fitted(self) -> dict | None:
        return self.adjustment.written_vs_fitted

    def own_warnings(self) -> list[str]:
        """The warnings that are the block's own (a scene moved beyond its stated accuracy), not
        also its adjustment's (those the adjustment's report shows and logs itself)."""
        shown = set(self.adjustment.warnings)
        return [w for w in self.warnings if w not in shown]

    def summary_sentence(self) -> str:
        """'block of 4 scenes: sigma0 0.912, tie RMS 9.120 px before, 0.310 px after; datum held by ...'."""
        block = self.block
        return (f"block of {block['scenes']} scenes: sigma0 {block['sigma0']:.3f}, tie RMS "
                f"{px_text(block['tie_rmse_before_px'])} before, {px_text(block['tie_rmse_px'])} after; {self.datum}")

    def log_lines(self) -> list[LogLine]:
        """What the log says of the block after its adjustment's sentences: per scene its control,
        check, tie and line figures and its move against its stated accuracy, the block's summary,
        without control its predicted absolute accuracy, and the block's own warnings."""
        accuracy = self.block.get("accuracy") or {}
        return [*(LogLine(scene_sentence(name, s)) for name, s in self.scenes.items()),
                LogLine(self.summary_sentence()), *(LogLine(text) for text in accuracy.get("sentences", [])),
                *(LogLine(w, True) for w in self.own_warnings())]


def scene_sentence(name: str, s: dict) -> str:
    """One block scene's figures (an entry of :attr:`BlockReport.scenes`) in words."""
    ties = s.get("ties")
    tie_text = f"; ties {px_text(ties['rmse_before_px'])} before, {px_text(ties['rmse_px'])} after" if ties else ""
    rpc = s.get("model") == "rpc"
    sigma = s["vendor_sigma_m" if rpc else "onboard_sigma_m"]
    source = "its vendor RPC (stated accuracy" if rpc else "its onboard geolocation (onboard sigma"
    lines = s.get("lines")
    line_text = f"; {lines['lines']} control lines ({lines['points']} points), across-line " \
        f"{metres_text(lines['across_rmse_before_m'])} before, {metres_text(lines['across_rmse_m'])} after" \
        if lines else ""
    control = f"control {px_text(s['control']['rmse_px'])} ({s['control']['observations']} obs.)" \
        if s["control"]["observations"] else "no control points"
    check = f"check {px_text(s['check_points']['rmse_px'])} ({s['check_points']['observations']} obs.)" \
        if s["check_points"]["observations"] else "no check points"
    return (f"scene {name}: {control}, {check}{tie_text}{line_text}; moved {s['moved_m']:.1f} m from {source} "
            f"{'-' if sigma is None else f'{sigma:.1f} m'}; stated {sigmas_text(s['sigmas'])})")

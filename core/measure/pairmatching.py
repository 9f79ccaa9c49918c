"""Tie points of a block on its overlap graph: every overlapping pair of images matched on its
own, the pairs' ties chained into multi-image tie points.

The pairs come from the images' footprints on the DEM through their onboard models
(:func:`overlap_pairs`, :mod:`core.products.overlaps`); a block the overlaps do not connect is
refused naming the images alone and the groups. Each pair (first, second), first the earlier
view given, is matched like :func:`core.measure.tiematching.match_block_tiepoints` with two
views: the first image's grid in the second image. Every pair with one first image shares that
image's grid points, so a ground point seen by k images is chained through them
(:func:`core.observations.tiechains.chain_pairs`) into one point of up to k observations.

Each pair's counts are reported (:class:`PairReport`: grid points, matched, rejected by reason,
refused in inconsistent chains), and the pairs with fewer than ``min_ties`` chained ties are named
in the log. Each pair is a picklable job (:class:`PairJob`, :func:`run_pair_job`: the same
matching, the DEM reopened by whoever runs it), run on this machine's threads or one after the
other (:func:`run_pair_jobs`), or on a Dask cluster (core.products.orthojobs.map_on_scheduler),
where the scenes travel as their files: the same ties to the bit whichever runs them.
"""
from __future__ import annotations

import logging
import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np

from ..dem import ConstantHeight, Dem
from ..errors import Cancelled, InputError
from ..formats import load_scene
from ..observations.tiechains import ChainResult, PairTies, chain_pairs
from ..products.footprint import footprints
from ..products.orthojobs import map_on_scheduler, surface_description
from ..products.overlaps import (Outline, OverlapGraph, disconnection, overlap_graph, refuse_disconnected,
                                tied_graph)
from .matching import MatchSettings, ground_sample_distance, reason_text
from .surface import filled_surface
from .tiematching import View, match_in_view, refuse_identical_images

log = logging.getLogger(__name__)

MIN_PAIR_TIES = 20            # chained ties below which a pair is named as weakly tied
FOOTPRINT_SAMPLES = 32        # outline points per image edge for the overlap graph
# px: one image's observations of a chain closer than this are one. Every pair of one first image
# shares its grid to the bit, the only positions of one ground point that meet; another image's
# matched position falls near a grid point of a later pair by chance, and merging two ground points
# 1 px apart (CHAIN_TOLERANCE_PX) averaged them: measured 0.48 px off the truth in the rendered
# tri-stereo of tests/qgis/test_matchtiepoints_block.py. Below the matching's precision (~0.02 px
# median) a chance meeting costs at most half of it.
PAIR_CHAIN_TOLERANCE_PX = 0.05


@dataclass(frozen=True)
class PairReport:
    """One pair's matching: the views' labels, the overlap of their footprints (km²), the first
    image's grid points, how many matched, rejected {reason: count} (REASONS of
    core.measure.matching), refused_in_chains: matched ties dropped with an inconsistent chain, and
    failure: '' or why the pair could not be matched at all (the matcher's error: e.g. no consistent
    offset between the two images within the search range)."""
    first: str
    second: str
    overlap_km2: float
    grid_points: int
    matched: int
    rejected: dict
    refused_in_chains: int = 0
    failure: str = ""

    @property
    def why(self) -> str:
        """What kept grid points out, in words."""
        return self.failure or reason_text(self.rejected)

    @property
    def chained(self) -> int:
        """Ties of this pair in the chained tie points."""
        return self.matched - self.refused_in_chains


def overlap_pairs(views: list[View], dem, min_area_km2: float = 0.0) -> OverlapGraph:
    """The overlap graph of ``views`` (named by their labels) from their footprints on ``dem``
    through their models (FOOTPRINT_SAMPLES points per image edge); InputError naming the scene
    whose footprint the DEM does not cover, and from :func:`core.products.overlaps.refuse_disconnected`
    when the overlaps do not connect the views."""
    outlines = []
    for v in views:
        try:
            f = footprints(v.scene, dem, cameras=[v.camera], samples_per_edge=FOOTPRINT_SAMPLES)[0]
        except InputError as exc:
            raise InputError(f"{v.scene_name}: {exc}", parameter="dem") from None
        outlines.append(Outline(v.label, f.lon, f.lat))
    graph = overlap_graph(outlines, min_area_km2)
    refuse_disconnected(graph)
    return graph


def match_pair(first: View, second: View, dem, settings: MatchSettings, overlap_km2: float = 0.0,
               progress: Callable[[float, str | None], None] | None = None,
               is_cancelled: Callable[[], bool] | None = None) -> tuple[PairTies, PairReport]:
    """``first``'s grid matched in ``second``'s image (see the module docstring): the ties (each
    with the match's sigma, px) and the pair's report. A pair the matcher refuses (InputError)
    gives no tie and says why in its report's ``failure``; the other pairs go on."""
    settings.validate()
    refuse_identical_images(first, [second])
    surface = filled_surface(first.scene, first.camera, dem)
    gsd = float(first.scene.info.get("gsd_m") or ground_sample_distance(first.scene, first.camera, surface))
    try:
        m, rejected = match_in_view(first, second, surface, gsd, settings,
                                    progress or (lambda fraction, message=None: None),
                                    is_cancelled or (lambda: False))
    except InputError as exc:        # this pair fails, the block goes on: reported with the pair
        nothing = np.empty(0)
        return (PairTies((first.scene_name, first.camera_name), (second.scene_name, second.camera_name),
                         nothing, nothing, nothing, nothing, nothing),
                PairReport(first.label, second.label, float(overlap_km2), 0, 0, {}, failure=str(exc)))
    ok = m.reasons < 0
    ties = PairTies((first.scene_name, first.camera_name), (second.scene_name, second.camera_name),
                    m.col[ok], m.row[ok], m.out["ref_col"][ok], m.out["ref_row"][ok], m.out["sigma"][ok])
    return ties, PairReport(first.label, second.label, float(overlap_km2), int(m.col.size), int(ok.sum()), rejected)


def match_overlap_graph(views: list[View], graph: OverlapGraph, dem, settings: MatchSettings = MatchSettings(),
                        min_ties: int = MIN_PAIR_TIES, tolerance_px: float = PAIR_CHAIN_TOLERANCE_PX,
                        scheduler: str = "", progress: Callable[[float, str | None], None] | None = None,
                        is_cancelled: Callable[[], bool] | None = None, processes: int = 0,
                        scene_files: dict | None = None) -> tuple[ChainResult, list[PairReport]]:
    """Match every pair of ``graph`` (over ``views``, in the graph's names order) as
    :class:`PairJob` s, on ``processes`` local processes (:func:`run_pair_jobs`) or on the Dask
    scheduler at ``scheduler`` (an address, e.g. tcp://host:8786; the views whose scene name
    ``scene_files`` holds travel there as their files: :func:`pair_jobs`), and chain the ties.
    Returns the chained tie points and each pair's report (refused_in_chains filled in).
    InputError when ``graph`` does not name ``views``, or when no pair gives a tie, with every
    pair's reasons."""
    if list(graph.names) != [v.label for v in views]:
        raise InputError("the overlap graph is not the given views'", parameter="scenes")
    jobs = pair_jobs(views, graph, dem, settings, scene_files if scheduler else None)
    results = run_pair_jobs(jobs, scheduler, progress, is_cancelled, processes)
    ties, reports = [t for t, _ in results], [r for _, r in results]
    if not any(len(t) for t in ties):
        raise InputError("no tie point matched in any overlapping pair: "
                         + "; ".join(f"{r.first}-{r.second}: {r.why}" for r in reports)
                         + ". Lower the quality threshold, enlarge the window or the search range, or check that "
                           "the images are the scenes'", parameter="scenes")
    chained = chain_pairs(ties, tolerance_px)
    reports = [replace(r, refused_in_chains=int(k)) for r, k in zip(reports, chained.refused_per_pair)]
    log_pairs(reports, chained, min_ties)
    apart = disconnection(tied_graph(graph, np.array([r.chained > 0 for r in reports], bool)))
    if apart:
        log.warning("the ties do not connect the block although the footprints do: %s (no tie of their pairs "
                    "was kept); the adjustment will refuse it until they are tied", apart)
    return chained, reports


@dataclass(frozen=True)
class SceneFileView:
    """A view as a job carries it to another process: its scene's file (read there, once per
    process: :func:`scene_of_file`) instead of the scene model (megabytes per job)."""
    scene_name: str
    scene_file: str
    camera: int
    image: Path
    label: str

    def view(self) -> View:
        return View(self.scene_name, scene_of_file(self.scene_file), self.camera, self.image)


@lru_cache(maxsize=64)
def scene_of_file(path: str):
    """The scene of the file ``path`` (:func:`core.formats.load_scene`), read once per process."""
    return load_scene(path)


@dataclass(frozen=True)
class PairJob:
    """One pair as a picklable job for another process or machine (this package importable, the
    images, the scene files and the DEM reachable at the same paths): the two views (each a View,
    its scene model pickling whole, or a :class:`SceneFileView`), the terrain as
    :func:`core.products.orthojobs.surface_description`, the settings and the pair's overlap (km²)."""
    first: View | SceneFileView
    second: View | SceneFileView
    surface: dict
    settings: MatchSettings
    overlap_km2: float = 0.0


def pair_jobs(views: list[View], graph: OverlapGraph, dem, settings: MatchSettings,
              scene_files: dict | None = None) -> list[PairJob]:
    """The jobs of every pair of ``graph`` (over ``views``), in the graph's pair order; a view whose
    scene name ``scene_files`` {scene name: the file its scene was read from, unchanged} holds
    travels as that file (:class:`SceneFileView`)."""
    files = scene_files or {}
    light = [SceneFileView(v.scene_name, str(Path(files[v.scene_name]).absolute()), v.camera, v.image, v.label)
             if v.scene_name in files else v for v in views]
    return [PairJob(light[a], light[b], surface_description(dem), settings, float(area))
            for (a, b), area in zip(graph.pairs, graph.area_km2)]


def run_pair_job(job: PairJob, progress: Callable[[float, str | None], None] | None = None,
                 is_cancelled: Callable[[], bool] | None = None) -> tuple[PairTies, PairReport]:
    """:func:`match_pair` of ``job``, the terrain reopened from its description (the scenes read
    from their files for :class:`SceneFileView` s)."""
    surface = (ConstantHeight(job.surface["height"]) if "height" in job.surface
               else Dem(job.surface["dem"], datum=job.surface["datum"]))
    first, second = (v.view() if isinstance(v, SceneFileView) else v for v in (job.first, job.second))
    return match_pair(first, second, surface, job.settings, job.overlap_km2, progress, is_cancelled)


def run_pair_jobs(jobs: list[PairJob], scheduler: str = "",
                  progress: Callable[[float, str | None], None] | None = None,
                  is_cancelled: Callable[[], bool] | None = None,
                  processes: int = 0) -> list[tuple[PairTies, PairReport]]:
    """The results of ``jobs`` in their order: on the Dask scheduler at ``scheduler`` (the same
    function on its workers: the same results), else on ``processes`` threads of this process (0:
    one per core; :func:`map_on_threads`), or with 1 one after the other (each pair's matching then
    uses the settings' threads). Cancelled when ``is_cancelled``."""
    report = progress or (lambda fraction, message=None: None)
    cancelled = is_cancelled or (lambda: False)
    if scheduler:
        return map_on_scheduler(scheduler, run_pair_job, jobs, lambda f: report(f, None), cancelled, "tie matching")
    processes = min(processes or os.cpu_count() or 1, len(jobs))
    if processes > 1:
        return map_on_threads(run_pair_job, [replace(j, settings=replace(j.settings, workers=1)) for j in jobs],
                              processes, lambda f: report(f, None), cancelled)
    results = []
    for n, job in enumerate(jobs):
        if cancelled():
            raise Cancelled("tie matching cancelled by the user")
        results.append(run_pair_job(job, lambda f, msg=None, n=n: report((n + f) / len(jobs), msg), cancelled))
    return results


def map_on_threads(function: Callable, jobs: list, threads: int, report: Callable[[float], None],
                   cancelled: Callable[[], bool]) -> list:
    """``function(job, None, cancelled)`` of each of ``jobs`` on ``threads`` threads, the results in
    the jobs' order. Threads, not processes: the matching runs in numpy, scipy and GDAL, which
    release the GIL, each job opens its own files (the DEM reopened from its description, the
    images by the matcher), and a fork of a process holding GDAL's and BLAS's threads can deadlock
    (measured: a fork pool hung at its first job); a spawned process would start QGIS again."""
    with ThreadPoolExecutor(max_workers=threads) as pool:
        futures = [pool.submit(function, job, None, cancelled) for job in jobs]
        try:
            for n, _ in enumerate(as_completed(futures)):
                report((n + 1) / len(jobs))
            return [f.result() for f in futures]
        finally:
            for f in futures:
                f.cancel()


def weak_pairs(reports: list[PairReport], min_ties: int = MIN_PAIR_TIES) -> list[PairReport]:
    """The pairs with fewer than ``min_ties`` chained ties."""
    return [r for r in reports if r.chained < min_ties]


def log_pairs(reports: list[PairReport], chained: ChainResult, min_ties: int) -> None:
    """The log's sentences on the pairs: how many matched and chained, the chains refused, and
    the pairs with too few ties, named."""
    matched = int(np.sum([r.matched for r in reports]))
    rays = ", ".join(f"{c} in {k} images" for k, c in sorted(chained.points_by_rays.items()))
    log.info("%d overlapping pairs matched: %d ties, chained into %d tie points (%s)", len(reports), matched,
             len(set(chained.table.id)), rays or "none")
    if chained.inconsistent_chains:
        log.warning("%d chains refused: each held two positions in one image more than the tolerance apart "
                    "(a mismatch in one of its pairs); their %d ties left out", chained.inconsistent_chains,
                    int(chained.refused_per_pair.sum()))
    weak = weak_pairs(reports, min_ties)
    if weak:
        log.warning("%d pair%s with fewer than %d ties: %s", len(weak), "s" * (len(weak) != 1), min_ties,
                    "; ".join(f"{r.first}-{r.second} ({r.chained}: {r.why})" for r in weak))

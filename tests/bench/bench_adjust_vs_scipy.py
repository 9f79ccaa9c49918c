"""Our adjustment against scipy.optimize.least_squares on the same problem, in one run.
Prints figures (no assertions).

Run:  cd /work/main && PROJ_DATA=/usr/share/proj /usr/bin/python3 tests/bench/bench_adjust_vs_scipy.py [--gcps 100000]

The problem: a simulated 5-scene CBERS-02B strip, --gcps ground points of which half are
control points (so the default 100 000 GCPs give the 50 000-control-point solution), 0.7 px
image noise, 3 m / 10 m weighted ground, orientation images every 20 s, the left and right
CCDs self-calibrated, no robust weighting. scipy gets the identical weighted residual vector
(image residuals, ground priors, GPS pseudo-observations) over the free parameters and the
ground corrections (3 per point), with the sparsity pattern of its Jacobian (finite
differences, 'trf' with LSMR, x_scale='jac'). Both start from the onboard model.

scipy runs twice. With 2-point differences and LSMR's default tolerances it stops early
(on ftol/xtol) above our minimum: the problem is ill-conditioned (position and attitude at a
knot correlate 0.9997) and those settings cannot follow its weak directions. With 3-point
differences and LSMR atol = btol = 1e-12 it reaches our solution; the speed ratio that counts
is that run's. The final weighted sums of squares and the CCD estimates (in our sigmas) are
compared for both.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import optimize, sparse

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
import tests.support.plugin_package  # noqa: E402,F401 (registers the package pushbroom_adjust)

from pushbroom_adjust.core.observations import gcps as G  # noqa: E402
from pushbroom_adjust.core.observations.tables import Heights  # noqa: E402
from pushbroom_adjust.core.adjust import AdjustmentSettings, adjust  # noqa: E402
from pushbroom_adjust.core.adjust.checks import check_inputs  # noqa: E402
from pushbroom_adjust.core.adjust.determinability import check_determinability  # noqa: E402
from pushbroom_adjust.core.adjust.problem import Problem  # noqa: E402
from pushbroom_adjust.core.adjust.solver import solve  # noqa: E402
from pushbroom_adjust.core.formats import load_scene  # noqa: E402
from pushbroom_adjust.simulation.measurements import GcpSettings  # noqa: E402
from pushbroom_adjust.simulation.simulator import simulate  # noqa: E402

SETTINGS = AdjustmentSettings(interior="HRC-1.*, HRC-3.*", position_model="lagrange", position_interval=20.0,
                              attitude_model="lagrange", attitude_interval=20.0, robust="none")


def scipy_problem(problem: Problem):
    """(residual function of x, x0, Jacobian sparsity) of the adjustment's weighted residuals;
    x = [free parameters, ground corrections (3 per point, m ECEF: ground - ground0)]."""
    free = problem.params.free
    n_p, m = free.size, problem.ground.shape[0]
    chol = np.linalg.cholesky(problem.ground_weight)           # P_G = L L'
    sqrt_w = np.sqrt(problem.weights())
    pseudo = problem.pseudo()

    def fun(x):
        values = problem.params.values()
        values[free] = x[:n_p]
        problem.params.set_values(values)
        problem.ground = problem.ground0 + x[n_p:].reshape(m, 3)
        image = (problem.residuals() * sqrt_w).ravel()
        ground = np.einsum("mji,mj->mi", chol, problem.ground - problem.ground0).ravel()
        prior = [np.sqrt(p.weight) * p.misfit(problem.params.values()) for p in pseudo]
        return np.concatenate([image, ground, *prior])

    rows, cols = [], []
    n = len(problem.obs)
    for k in range(2):  # image rows: their parameter columns and their point's 3 ground columns
        r = 2 * np.arange(n) + k
        c = problem.columns
        keep = c >= 0
        rows.append(np.repeat(r, c.shape[1])[keep.ravel()])
        cols.append(c[keep])
        rows.append(np.repeat(r, 3))
        cols.append((n_p + 3 * problem.obs.point[:, None] + np.arange(3)).ravel())
    g = 2 * n + np.arange(3 * m)  # ground-prior rows: their point's 3 columns
    rows.append(np.repeat(g, 3))
    cols.append((n_p + 3 * (np.arange(3 * m) // 3)[:, None] + np.arange(3)).ravel())
    start = 2 * n + 3 * m
    for p in pseudo:
        r = start + np.arange(p.B.shape[0])
        rows.append(np.repeat(r, p.index.size))
        cols.append(np.tile(problem.unknown[p.index], r.size))
        start += r.size
    pattern = sparse.coo_matrix((np.ones(sum(a.size for a in rows)), (np.concatenate(rows), np.concatenate(cols))),
                                shape=(start, n_p + 3 * m)).tocsr()
    pattern.data[:] = 1
    x0 = np.concatenate([problem.params.values()[free], (problem.ground - problem.ground0).ravel()])
    return fun, x0, pattern


def prepared(scene, table) -> Problem:
    """The adjustment's problem with the free parameters adjust() solves for."""
    problem = Problem(scene, table, SETTINGS)
    check_determinability(problem, problem.system()[1])
    return problem


SCIPY = {  # label: options of least_squares besides the sparsity pattern
    "2-point, LSMR defaults": dict(jac="2-point"),
    "3-point, LSMR atol=btol=1e-12": dict(jac="3-point", tr_options=dict(atol=1e-12, btol=1e-12)),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--gcps", type=int, default=100_000, help="all GCPs, half of them check points")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        r = simulate("cbers02b_hrc", tmp, seed=1, n_scenes=5,
                     gcp_settings=GcpSettings(n_gcps=args.gcps, image_noise=0.7, check_fraction=0.5,
                                              ground_noise_xy=3.0, ground_noise_z=10.0))
        table = G.read_csv(r.gcps, G.CsvMapping(z="h", role="role", camera="camera"), "EPSG:4326",
                           Heights("z", datum="ellipsoid"), sigma_px=0.7, sigma_xy=3.0, sigma_z=10.0)
        scene = load_scene(r.onboard_scene)
    t0 = time.perf_counter()
    ours = adjust(scene, table, SETTINGS)
    t_ours = time.perf_counter() - t0
    ours_cost = ours.report["iterations"][-1]["cost"]
    # the solver alone, as scipy's is alone: set-up, statistics and reports excluded
    checked = check_inputs(scene, table, SETTINGS)
    problem = prepared(scene, checked)
    t0 = time.perf_counter()
    solve(problem, lambda *a: None, lambda: False)
    t_solve = time.perf_counter() - t0
    fun, x0, pattern = scipy_problem(prepared(scene, checked))
    print(f"{len(table)} GCPs, {int(np.sum(table.role == 'check'))} of them check points: "
          f"{problem.ground.shape[0]} control points in the solution ({len(problem.obs)} image observations); "
          f"unknowns: {problem.params.free.size} parameters + {problem.ground.size} ground coordinates; "
          f"Jacobian {pattern.shape[0]} x {pattern.shape[1]}, {pattern.nnz} non-zeros")
    print(f"ours, complete adjustment (statistics, check points, report): {t_ours:.2f} s, weighted sum of squares "
          f"{ours_cost:.8g}")
    print(f"ours, solver alone (same start, same problem): {t_solve:.2f} s, weighted sum of squares "
          f"{problem.cost():.8g}")
    reported = {p["name"]: p for p in ours.report["parameters"]}
    ccd = [(k, reported[problem.params.params[i].name]) for k, i in enumerate(problem.params.free)
           if problem.params.params[i].name.startswith("HRC-")]
    for label, options in SCIPY.items():
        t0 = time.perf_counter()
        sol = optimize.least_squares(fun, x0, jac_sparsity=pattern, method="trf", tr_solver="lsmr", x_scale="jac",
                                     ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=500, **options)
        t_scipy = time.perf_counter() - t0
        cost = float(2 * sol.cost)
        worst = max(abs(sol.x[k] - p["value"]) / p["sigma"] for k, p in ccd)
        print(f"scipy least_squares ({label}): {t_scipy:.1f} s, {sol.nfev} function and {sol.njev} Jacobian "
              f"evaluations, status {sol.status} ({sol.message}); weighted sum of squares {cost:.8g} "
              f"(relative to ours {cost / ours_cost - 1:+.1e}); the {len(ccd)} CCD estimates within "
              f"{worst:.3f} of our sigmas; speed ratio scipy / our solver {t_scipy / t_solve:.1f}x, "
              f"scipy / our complete adjustment {t_scipy / t_ours:.1f}x")


if __name__ == "__main__":
    main()

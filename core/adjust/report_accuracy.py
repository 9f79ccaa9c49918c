"""What a block of RPC products held without control can claim of its absolute accuracy (issue 31):
each product's predicted error against its prior, the block's common error, and the tie points'
heights against the reference DEM.

Without control points a block's position is held by virtual control: every product's vendor RPC at
its stated accuracy (RPC_SIGMA, Grodecki & Dial 2003) and, with DEM and TIE_HEIGHT_SIGMA, the reference
DEM under the tie points. The tie points make the products move together, so what is left of each
product's error is mostly the error the block shares, and that common error is the mean of n
independent vendor errors: its sigma falls as the prior's over sqrt(n) (the regional GCP-free RFM
adjustments of ZY-3 blocks rest on this). The figures here come from the adjustment's own statistics:

- per product, the posterior sigma of its shift terms a0 and b0 (px: the correction at the image's first
  row, where the drift terms add nothing) from the stated sigmas (the parameter table's sigma over the
  adjusted sigma0 it is scaled by: the priors hold what matters here, and the tie points' fit says nothing
  of the vendors' errors) against its prior sigma (rpc_sigma, px), both also in metres at the image
  centre's ground sample distance;
- the block's common shift: the posterior sigma of the moves 'shift east' and 'shift north' of the whole
  block (:mod:`core.adjust.datumdirections`: the priors' sigma along them combined with what the
  observations, the DEM's rows included, give), with what the priors alone predict, prior / sqrt(n);
- the tie points' heights: the RMS of (adjusted height - DEM height) over the points the DEM holds,
  against 1.5 times TIE_HEIGHT_SIGMA, with the points left free and why.
"""
from __future__ import annotations

import math

HEIGHT_FACTOR = 1.5   # tie heights within this times TIE_HEIGHT_SIGMA (RMS) agree with the reference DEM
SHIFTS = ("shift east", "shift north")


def product_errors(scenes: dict, scale: float = 1.0) -> dict | None:
    """Per RPC product of a block report's ``scenes`` (:func:`core.adjust.blockreport.block_report`):
    its shift terms' posterior sigma (px, the larger of a0 and b0; times ``scale``) against its prior
    (rpc_sigma px), and
    in metres. Returns {products, within, beyond (names), largest_ratio, predicted_m (median, largest),
    prior_m (smallest, largest), virtual_control_m: the radial sigma (m) of the mean of the products'
    independent priors, sqrt(2 / sum(1 / prior_m^2)),
    sqrt(2) x prior / sqrt(n) for equal priors}; None without RPC products with a prior and free shift terms."""
    rows = []
    for name, s in scenes.items():
        terms = s.get("correction") or {}
        prior = (s.get("sigmas") or {}).get("rpc_sigma_px")
        sigmas = [scale * terms[t]["sigma"] for t in ("a0", "b0") if t in terms and terms[t]["sigma"] is not None]
        if s.get("model") != "rpc" or not prior or not sigmas or not s.get("vendor_sigma_m"):
            continue
        gsd = s["vendor_sigma_m"] / prior
        rows.append((name, max(sigmas), prior, gsd))
    if not rows:
        return None
    beyond = [name for name, sigma, prior, _ in rows if sigma > prior]
    metres = sorted(sigma * gsd for _, sigma, _, gsd in rows)
    priors = [prior * gsd for _, _, prior, gsd in rows]
    return {"products": len(rows), "within": len(rows) - len(beyond), "beyond": beyond,
            "largest_ratio": max(sigma / prior for _, sigma, prior, _ in rows),
            "predicted_m": {"median": metres[len(metres) // 2], "largest": metres[-1]},
            "prior_m": {"smallest": min(priors), "largest": max(priors)},
            "virtual_control_m": math.sqrt(2.0 / sum(1.0 / p ** 2 for p in priors))}


def common_shift(directions: list, products: dict) -> dict | None:
    """The block's common horizontal error predicted by the statistics, from the adjustment's datum
    ``directions`` (:func:`core.adjust.datumdirections.datum_directions`): per axis (east, north) the
    posterior sigma 1 / sqrt(1 / prior^2 + 1 / obs^2) (m) and what held it; ``horizontal_m`` the
    radial sigma sqrt(east^2 + north^2), ``priors_horizontal_m`` the priors' alone; ``products``
    and ``virtual_control_m`` from :func:`product_errors` (what their independent priors give). None when the datum
    analysis names no horizontal shift (control holds it, or the corrections cannot follow it)."""
    found = {d["direction"]: d for d in directions if d["direction"] in SHIFTS}
    if len(found) < 2:
        return None
    axes = {}
    for name in SHIFTS:
        d = found[name]
        info = 1.0 / d["prior_sigma_m"] ** 2 + (1.0 / d["ties_sigma_m"] ** 2 if d.get("ties_sigma_m") else 0.0)
        axes[name.split()[1]] = {"sigma_m": 1.0 / math.sqrt(info), "prior_sigma_m": d["prior_sigma_m"],
                                 "held_by": d["held_by"]}
    return {**axes, "products": products["products"], "virtual_control_m": products["virtual_control_m"],
            "horizontal_m": math.hypot(axes["east"]["sigma_m"], axes["north"]["sigma_m"]),
            "priors_horizontal_m": math.hypot(axes["east"]["prior_sigma_m"], axes["north"]["prior_sigma_m"])}


def height_agreement(heights: dict | None) -> dict | None:
    """The tie points' heights against the reference DEM (``report["tie_points"]["heights"]``,
    :meth:`core.adjust.tieheights.HeightConstraint.counts`): RMS (m) against HEIGHT_FACTOR x sigma,
    the points used and left free (off the DEM, on its holes). None without a reference DEM."""
    if not heights or heights.get("misfit_rms_m") is None:
        return None
    limit = HEIGHT_FACTOR * heights["sigma_m"]
    return {"rms_m": heights["misfit_rms_m"], "limit_m": limit, "within": heights["misfit_rms_m"] <= limit,
            "used": heights["constrained"], "off_dem": heights["off_dem"], "on_holes": heights["on_holes"]}


def absolute_accuracy(scenes: dict, adjustment, controlled: bool) -> dict | None:
    """A block's absolute-accuracy figures (see the module docstring): ``products``
    (:func:`product_errors`), ``common_shift`` (:func:`common_shift`), ``heights``
    (:func:`height_agreement`) and ``sentences`` saying them; None for a block with control points
    (its check points say its accuracy) or without RPC products."""
    if controlled:
        return None
    sigma0 = adjustment.get("sigma0_adjusted")
    products = product_errors(scenes, 1.0 / sigma0 if sigma0 else 1.0)
    if products is None:
        return None
    shift = common_shift((adjustment.get("datum") or {}).get("directions", []), products)
    heights = height_agreement(((adjustment.get("tie_points") or {}).get("heights")))
    out = {"products": products, "common_shift": shift, "heights": heights}
    return {**out, "sentences": accuracy_sentences(out)}


def accuracy_sentences(acc: dict) -> list[str]:
    """The figures of :func:`absolute_accuracy` in words, one sentence each."""
    p = acc["products"]
    beyond = f"; beyond it: {', '.join(p['beyond'][:20])}{' ...' if len(p['beyond']) > 20 else ''}" \
        if p["beyond"] else ""
    out = [f"predicted absolute error of each product (posterior sigma of its shift terms, no control points): "
           f"{p['within']} of {p['products']} products within their prior (vendor RPC_SIGMA), median "
           f"{p['predicted_m']['median']:.2f} m, largest {p['predicted_m']['largest']:.2f} m per axis against "
           f"{p['prior_m']['largest']:.1f} m{beyond}"]
    s = acc["common_shift"]
    if s:
        vc = (f"; the priors alone give {s['priors_horizontal_m']:.2f} m, {s['products']} independent priors "
              f"{s['virtual_control_m']:.2f} m (sqrt(2) x prior / sqrt(n))")
        out.append(f"predicted error of the whole block's horizontal position (its common shift): "
                   f"{s['horizontal_m']:.2f} m (1 sigma, radial; east held by {s['east']['held_by']}, north by "
                   f"{s['north']['held_by']}){vc}")
    h = acc["heights"]
    if h:
        left = h["off_dem"] + h["on_holes"]
        free = f"; {left} left free ({h['off_dem']} off the DEM, {h['on_holes']} on its holes)" if left else ""
        out.append(f"tie point heights against the reference DEM: {h['rms_m']:.2f} m RMS over {h['used']} points, "
                   f"{'within' if h['within'] else 'beyond'} {HEIGHT_FACTOR:g} x TIE_HEIGHT_SIGMA = "
                   f"{h['limit_m']:.2f} m{free}")
    return out

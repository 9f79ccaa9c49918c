"""Tie points' heights held to a reference DEM: DEM with TIE_HEIGHT_SIGMA (m).

A block tied without enough control has no height datum but its products' priors: the moves of the
whole block its corrections follow (a height shift, height tilts, :mod:`core.adjust.datumdirections`)
are held only as tightly as the priors hold them (issue 31: the default RPC_CORRECTION=drift tilted a
ties-only Pleiades triplet's heights by 13.5 m over 512 m, held only by the 10 px prior). A reference
DEM (SRTM, Copernicus GLO-30) at its stated accuracy holds them, as the GCP-free regional RFM
adjustments of ZY-3 and GF-1 blocks do (virtual control from a reference DEM for the heights).

Each tie point gets one pseudo-observation: its ellipsoidal height minus the DEM's ellipsoidal height
at its current longitude and latitude (:meth:`core.dem.Dem.height`: a geoid-referenced DEM is
converted at the point by EGM96), weight 1 / sigma^2 along its local up direction only (rank 1 in
its ECEF ground prior, :class:`core.adjust.normal.GroundPrior`), so that it holds the point's height
and leaves its horizontal position to the rays. The DEM's slope is not differentiated: the misfit is
re-evaluated at every linearisation, where the point is then. Points off the DEM or on its nodata
holes get no constraint and are counted. The rows count among the equations (one per constrained
point), their misfits enter sigma0, and their sum of p v^2 and redundancy form the group
TIE_HEIGHT_GROUP, weighted at the stated sigma: its factor is not estimated (it holds the vertical
datum, as the onboard priors do when they alone hold it; :func:`core.adjust.robust.datum_groups`),
and its ratio estimated / stated says how well the DEM and the adjusted heights agree.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..dem import Dem
from ..errors import InputError
from ..geodesy import ecef_to_geodetic, enu_rotations

# The pseudo-observation group of the tie points' heights above the reference DEM
TIE_HEIGHT_GROUP = "tie heights (reference DEM)"
# m: plausible stated accuracies of a reference DEM, from a lidar DEM's centimetres to a kilometre
TIE_HEIGHT_SIGMA_RANGE = (0.01, 1000.0)


@dataclass
class HeightConstraint:
    """The tie points' height constraint at their current ground (t points): ``up`` (t,3) their
    local up unit vectors (ECEF), ``dh`` (t,) m their ellipsoidal height minus the DEM's (NaN
    where the DEM gives none), ``off`` / ``hole`` (t,) bool: off the DEM's extent / on its nodata,
    ``sigma`` m the stated accuracy."""
    up: np.ndarray
    dh: np.ndarray
    off: np.ndarray
    hole: np.ndarray
    sigma: float

    @property
    def on(self) -> np.ndarray:
        """(t,) bool: the points constrained."""
        return np.isfinite(self.dh)

    @property
    def weight(self) -> np.ndarray:
        """(t,3,3) 1/m^2 ECEF: u u' / sigma^2 for the points constrained, 0 for the others."""
        w = np.where(self.on, 1.0 / self.sigma ** 2, 0.0)
        return w[:, None, None] * self.up[:, :, None] * self.up[:, None, :]

    @property
    def misfit(self) -> np.ndarray:
        """(t,3) m ECEF: dh u (its component along up is the height misfit; 0 where unconstrained)."""
        return np.where(self.on, self.dh, 0.0)[:, None] * self.up

    @property
    def cost(self) -> float:
        """Sum of the weighted squared height misfits."""
        return float(np.sum(self.dh[self.on] ** 2)) / self.sigma ** 2

    def sums(self, qgg: np.ndarray) -> tuple[float, float, int]:
        """(sum of p v^2, redundancy, count) of the constrained points' rows, with the posterior
        cofactors ``qgg`` (t,3,3) ECEF m^2 of their ground unknowns: r = 1 - u' Q u / sigma^2."""
        on = self.on
        u = self.up[on]
        r = np.clip(1.0 - np.einsum("ni,nij,nj->n", u, qgg[on], u) / self.sigma ** 2, 0.0, 1.0)
        return self.cost, float(r.sum()), int(on.sum())

    def counts(self) -> dict:
        """The report's figures: points constrained, off the DEM, on its holes; the height misfits'
        RMS and largest (m) over the constrained points."""
        d = self.dh[self.on]
        return {"sigma_m": self.sigma, "constrained": int(d.size), "off_dem": int(self.off.sum()),
                "on_holes": int(self.hole.sum()),
                "misfit_rms_m": float(np.sqrt(np.mean(d ** 2))) if d.size else None,
                "misfit_max_m": float(np.abs(d).max()) if d.size else None}


@dataclass
class TieHeights:
    """The reference DEM ``surface`` (:class:`core.dem.Dem`, ellipsoidal heights) and its stated
    accuracy ``sigma`` (m)."""
    surface: Dem
    sigma: float

    def __deepcopy__(self, memo) -> "TieHeights":
        """The same reference: a copied problem (the interior selection's trials) reads the same DEM."""
        return self

    def at(self, ground: np.ndarray) -> HeightConstraint:
        """The constraint of tie points at ``ground`` (t,3) ECEF m."""
        lon, lat, h = ecef_to_geodetic(ground)
        dh = h - self.surface.height(lon, lat) if len(ground) else np.zeros(0)
        missing = ~np.isfinite(dh)
        off, hole = np.zeros(dh.shape, bool), np.zeros(dh.shape, bool)
        if missing.any():
            off[missing], hole[missing] = self.surface.no_height(lon[missing], lat[missing])
        return HeightConstraint(enu_rotations(lon, lat)[:, 2], dh, off, hole, self.sigma)

    def check_covers(self, ground: np.ndarray) -> None:
        """InputError (concerning the DEM) when the DEM gives a height at none of the tie points at
        ``ground`` (t,3) ECEF m: it would hold nothing of the block's heights."""
        c = self.at(ground)
        if len(ground) and not c.on.any():
            raise InputError(f"the reference DEM {self.surface.path} gives no height at any of the {len(ground)} tie "
                             f"points ({int(c.off.sum())} off its extent, {int(c.hole.sum())} on its nodata holes): "
                             "give a DEM that covers the block", parameter="settings.dem")

    def sentence(self, counts: dict) -> str:
        """The constraint in words for the report and the log."""
        left = [f"{n} {why}" for n, why in ((counts["off_dem"], "off the DEM"), (counts["on_holes"], "on its holes"))
                if n]
        fit = f"; their heights fit it to {counts['misfit_rms_m']:.2f} m RMS" if counts["constrained"] else ""
        return (f"{counts['constrained']} tie points held to the reference DEM {self.surface.path} at "
                f"{self.sigma:g} m (TIE_HEIGHT_SIGMA)" + (f", {', '.join(left)} left free" if left else "") + fit)


def reference_of(dem: str, datum: str, sigma: float | None) -> TieHeights | None:
    """The reference DEM of the settings (None without TIE_HEIGHT_SIGMA)."""
    return TieHeights(Dem(dem, datum), float(sigma)) if sigma is not None else None

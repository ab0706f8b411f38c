"""Where success crosses γ: the logistic fit or its centered-isotonic fallback, for breakpoint.break_point."""

from __future__ import annotations

import math

import numpy as np

from indgen_vla.core.errors import ConfigError

GOF_P = 0.05  # deviance goodness-of-fit p-value below which the logistic fit is called poor


def pava_decreasing(y: np.ndarray, w: np.ndarray) -> list[tuple[int, int, float]]:
    """Pool-adjacent-violators for a non-increasing fit; returns blocks (first, last, value)."""
    blocks: list[list[float]] = []  # [first, last, weighted sum, weight]
    for i, (yi, wi) in enumerate(zip(y, w, strict=True)):
        blocks.append([i, i, yi * wi, wi])
        while len(blocks) > 1 and blocks[-2][2] / blocks[-2][3] < blocks[-1][2] / blocks[-1][3]:
            b = blocks.pop()
            blocks[-1][1] = b[1]
            blocks[-1][2] += b[2]
            blocks[-1][3] += b[3]
    return [(int(b[0]), int(b[1]), b[2] / b[3]) for b in blocks]


def isotonic_crossing(x: np.ndarray, s: np.ndarray, n: np.ndarray, gamma: float) -> float:
    """Centered isotonic regression (Oron & Flournoy 2017): each PAVA block sits at its n-weighted mean x;
    the crossing of γ is linearly interpolated between those points. ±inf when it lies outside x's range."""
    blocks = pava_decreasing(s / n, n)
    px = [float(np.average(x[a : b + 1], weights=n[a : b + 1])) for a, b, _ in blocks]
    py = [v for _, _, v in blocks]
    if py[0] < gamma:
        return -math.inf
    for i in range(len(py) - 1):
        if py[i] >= gamma > py[i + 1]:
            return px[i] + (py[i] - gamma) / (py[i] - py[i + 1]) * (px[i + 1] - px[i])
    return math.inf


def _separated(x: np.ndarray, s: np.ndarray, n: np.ndarray) -> bool:
    """(Quasi-)complete separation or all-one-outcome: the logistic MLE does not exist."""
    has_s, has_f = s > 0, s < n
    if not has_s.any() or not has_f.any():
        return True
    return bool(x[has_s].max() <= x[has_f].min())


def logistic_fit(x: np.ndarray, s: np.ndarray, n: np.ndarray, iters: int = 50) -> tuple[float, float, bool]:
    """Binomial GLM logit(S) = a + b·x by Newton–Raphson (IRLS); returns (a, b, converged)."""
    p0 = np.clip(s.sum() / n.sum(), 1e-3, 1 - 1e-3)
    theta = np.array([math.log(p0 / (1 - p0)), 0.0])
    xm = np.stack([np.ones_like(x), x], axis=1)
    for _ in range(iters):
        mu = 1 / (1 + np.exp(-(xm @ theta)))
        wgt = n * mu * (1 - mu)
        grad = xm.T @ (s - n * mu)
        hess = xm.T @ (xm * wgt[:, None])
        try:
            step = np.linalg.solve(hess, grad)
        except np.linalg.LinAlgError:
            return float(theta[0]), float(theta[1]), False
        theta = theta + step
        if np.abs(step).max() < 1e-10:
            return float(theta[0]), float(theta[1]), True
    return float(theta[0]), float(theta[1]), False


def deviance_p(x, s, n, a, b) -> float:
    """Goodness of fit of the logistic curve: residual deviance against χ² with (levels − 2) df."""
    from scipy.special import chdtrc  # χ² survival function; lighter to import than scipy.stats

    df = len(x) - 2
    if df < 1:
        return 1.0
    mu = np.clip(1 / (1 + np.exp(-(a + b * x))), 1e-12, 1 - 1e-12)
    f = n - s
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(s > 0, s * np.log(s / (n * mu)), 0.0)
        t2 = np.where(f > 0, f * np.log(f / (n * (1 - mu))), 0.0)
    return float(chdtrc(df, 2 * float((t1 + t2).sum())))


def crossing(
    x: np.ndarray, s: np.ndarray, n: np.ndarray, gamma: float, method: str = "auto", gof: bool = True
) -> tuple[float, str, str]:
    """Where the success curve crosses γ, in |level| units: (x_c, method used, why).

    x_c is ±inf when the crossing lies before the first or beyond the last level evaluated. `gof=False`
    skips the lack-of-fit check (bootstrap replicates keep the method chosen on the data).
    """
    keep = n > 0
    x, s, n = x[keep], s[keep], n[keep]
    if len(x) < 2:
        raise ConfigError("the break point needs at least two levels with finished episodes in a direction")
    why = ""
    if method in ("auto", "logistic"):
        if _separated(x, s, n):
            why = "no logistic MLE (separated or one outcome only)"
        else:
            a, b, ok = logistic_fit(x, s, n)
            if not ok:
                why = "logistic fit did not converge"
            elif b >= 0:
                why = "logistic slope has the wrong sign (success does not fall with the level)"
            elif gof and (p := deviance_p(x, s, n, a, b)) < GOF_P:
                why = f"logistic lack of fit (deviance p = {p:.3g} < {GOF_P})"
            else:
                xc = (math.log(gamma / (1 - gamma)) - a) / b
                if xc < x[0]:
                    xc = -math.inf
                elif xc > x[-1]:
                    xc = math.inf
                return xc, "logistic", "logistic fit accepted"
        if method == "logistic":
            raise ConfigError(f"logistic break point unavailable: {why}; use method='auto' or 'isotonic'")
    elif method != "isotonic":
        raise ConfigError(f"unknown break-point method {method!r}; use 'auto', 'logistic' or 'isotonic'")
    return isotonic_crossing(x, s, n, gamma), "isotonic", why or "isotonic requested"


def logistic_crossings(x: np.ndarray, s: np.ndarray, n: np.ndarray, gamma: float, iters: int = 40):
    """Vectorised Newton fits of many replicates (rows); returns crossings (|level| units) and which rows
    gave a valid fit (no separation, converged, falling slope). Rows with n == 0 at a level weigh nothing."""
    has_s, has_f = s > 0, s < n
    xs = np.where(has_s, x, -np.inf).max(1)
    xf = np.where(has_f, x, np.inf).min(1)
    valid = has_s.any(1) & has_f.any(1) & (xs > xf)
    p0 = np.clip(s.sum(1) / np.maximum(n.sum(1), 1), 1e-3, 1 - 1e-3)
    a, b = np.log(p0 / (1 - p0)), np.zeros(len(s))
    conv = np.zeros(len(s), dtype=bool)
    for _ in range(iters):
        mu = 1 / (1 + np.exp(-(a[:, None] + b[:, None] * x)))
        r = s - n * mu
        wgt = n * mu * (1 - mu)
        g0, g1 = r.sum(1), (r * x).sum(1)
        h00, h01, h11 = wgt.sum(1), (wgt * x).sum(1), (wgt * x * x).sum(1)
        det = h00 * h11 - h01 * h01
        det = np.where(np.abs(det) > 1e-300, det, np.nan)
        da, db = (h11 * g0 - h01 * g1) / det, (h00 * g1 - h01 * g0) / det
        da, db = np.where(valid, da, 0.0), np.where(valid, db, 0.0)
        a, b = a + da, b + db
        conv = np.abs(da).clip(0) + np.abs(db) < 1e-9
    ok = valid & conv & (b < 0) & np.isfinite(a) & np.isfinite(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = (math.log(gamma / (1 - gamma)) - a) / b
    xc = np.where(xc < x[0], -np.inf, np.where(xc > x[-1], np.inf, xc))
    return np.where(ok, xc, np.nan), ok

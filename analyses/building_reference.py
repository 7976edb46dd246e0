r"""The input-output reference of the five-storey building (``building.py``, issue 33).

A mode is :math:`a_j/f = A_j(-\omega^2)/(\omega_r^2 - \omega^2 + 2i\zeta_r\omega_r\omega) + R_j`
over its band, jointly over the floors, :math:`A_j` real (its shape), by variable
projection: fitted to the raw records in the time domain (each floor predicted from the
measured force, both band-passed; the reference, its uncertainty the standard error over
the record's quarters) and to the H1 FRFs (the model smoothed by the Hann kernel, weights
from the coherence; shown beside it, it moves with the window).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize, signal

DT = 0.01  # s
BANDS = ((0.42, 0.65), (1.5, 2.05))  # Hz
NPERSEG = 8192


def frfs(force, floors, nperseg=NPERSEG):
    """Frequencies (Hz), H1 ``(5, F)`` and coherence ``(5, F)``."""
    kw = {"fs": 1 / DT, "window": "hann", "nperseg": nperseg}
    (_, s_ff), (_, s_aa) = signal.welch(force, **kw), signal.welch(floors.T, axis=-1, **kw)
    f, s_fa = signal.csd(force[None], floors.T, axis=-1, **kw)
    return f, s_fa / s_ff, np.abs(s_fa) ** 2 / (s_ff * s_aa)


def accelerance(w, wr, z):
    """One mode's accelerance per unit residue."""
    return -(w**2) / (wr**2 - w**2 + 2j * z * wr * w)


def _project(design, y, weights):
    """Weighted residuals and real coefficients ``(k, 5)`` of ``design`` for ``y``."""
    res, coef = [], []
    for j in range(y.shape[1]):
        M, t = design * weights[:, j, None], y[:, j] * weights[:, j]
        if np.iscomplexobj(M):
            M, t = np.vstack([M.real, M.imag]), np.r_[t.real, t.imag]
        c = np.linalg.lstsq(M, t, rcond=None)[0]
        res.append(t - M @ c)
        coef.append(c)
    return np.concatenate(res), np.array(coef).T


def _modal_fit(design, y, weights, band, start=None) -> dict:
    """``(w_r, z_r)`` by least squares over ``band`` (Hz), from ``start`` or a grid."""
    lo, hi = 2 * math.pi * np.array(band)
    starts = [start] if start is not None else [(w, 0.02) for w in np.linspace(lo, hi, 7)[1:-1]]

    def residual(p):
        return _project(design(p), y, weights)[0]

    fits = [optimize.least_squares(residual, s, bounds=([lo, 1e-4], [hi, 0.3]),
                                   x_scale=[0.1, 0.01]) for s in starts]  # fmt: skip
    p = min(fits, key=lambda r: r.cost).x
    coef = _project(design(p), y, weights)[1]
    shape = coef[0] / coef[0][np.argmax(np.abs(coef[0]))]
    return {"wa": p[0], "f": p[0] / (2 * math.pi), "zeta": p[1], "shape": shape, "coef": coef}


def frf_fit(force, floors, band, nperseg=NPERSEG) -> dict:
    """One mode from H1, the model smoothed by the Hann window's kernel |W|^2 (on an
    8-times finer grid, +-6 bins), weighted by H1's standard error from the coherence."""
    f, H, coh = frfs(force, floors, nperseg)
    sel = (f >= band[0]) & (f <= band[1])
    g, Hs = np.clip(coh[:, sel].T, 1e-3, 0.999), H[:, sel].T
    weights = np.sqrt((2 * len(force) // nperseg - 1) * 2 * g / (1 - g)) / np.abs(Hs)
    W = np.abs(np.fft.fft(signal.get_window("hann", nperseg), 8 * nperseg)) ** 2
    k = np.arange(-48, 49)
    K = W[k % W.size] / W[k % W.size].sum()
    w = 2 * math.pi * (f[sel][:, None] + k[None] / (8 * nperseg * DT))

    def design(p):
        return np.column_stack([(K * accelerance(w, *p)).sum(1), np.ones(sel.sum())])

    return _modal_fit(design, Hs, weights, band)


def time_fit(force, floors, band, start=None, part=4) -> dict:
    """One mode by the output-error fit (the accelerance's bilinear transform, ``wa``
    pre-warped back to ``f``) on the record but its ends, or its quarter ``part``."""
    sos = signal.butter(4, band, "bandpass", fs=1 / DT, output="sos")
    u, y = signal.sosfiltfilt(sos, force), signal.sosfiltfilt(sos, floors, axis=0)
    m = (len(u) - 6000) // 4
    keep = slice(3000, -3000) if part == 4 else slice(3000 + part * m, 3000 + (part + 1) * m)

    def design(p):
        den = [1, 2 * p[1] * p[0], p[0] ** 2]
        num, den, _ = signal.cont2discrete(([1, 0, 0], den), DT, method="bilinear")
        return np.column_stack([signal.lfilter(num.ravel(), den, u), u])[keep]

    out = _modal_fit(design, y[keep], np.ones(y[keep].shape), band, start)
    out["f"] = 2 / DT * math.atan(out["wa"] * DT / 2) / (2 * math.pi)
    return out


def reference(force, floors) -> list[dict]:
    """Per mode: the time-domain fit, its quarters, the FRF fit, its halves and windows,
    the coherence near the mode (mean over the floors within 3 % of f); for mode 1 both
    fits on a simulated mode (``sim``)."""
    out, n = [], len(force)
    f, _, coh = frfs(force, floors)
    for band in BANDS:
        ref = time_fit(force, floors, band)
        ref["parts"] = [time_fit(force, floors, band, (ref["wa"], ref["zeta"]), i)
                        for i in range(4)]  # fmt: skip
        fr = frf_fit(force, floors, band)
        fr["parts"] = [frf_fit(force[s], floors[s], band)
                       for s in (slice(n // 2), slice(n // 2, n))]  # fmt: skip
        for m, key in ((m, key) for m in (ref, fr) for key in ("f", "zeta")):
            m[f"{key}_err"] = np.std([p[key] for p in m["parts"]], ddof=1) / len(m["parts"]) ** 0.5
        fr["windows"] = {n: frf_fit(force, floors, band, n)["zeta"] for n in (4096, 16384)}
        near = np.abs(f - ref["f"]) <= 0.03 * ref["f"]
        out.append({**ref, "frf": fr, "coherence": float(coh[:, near].mean()), "band": band})
    # both fits on floors made from the measured force through mode 1 at 2 %, 10 % noise
    r, z = out[0], 0.02
    tf = signal.cont2discrete(([1, 0, 0], [1, 2 * z * r["wa"], r["wa"] ** 2]), DT, "bilinear")
    y = signal.lfilter(tf[0].ravel(), tf[1], force)[:, None] * r["coef"][0][None]
    y = y + 0.1 * y.std() * np.random.default_rng(0).standard_normal(y.shape)
    r["sim"] = [time_fit(force, y, BANDS[0])["zeta"], frf_fit(force, y, BANDS[0])["zeta"]]
    return out

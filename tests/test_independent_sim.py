"""The independent simulator's forces (analyses/independent_sim.py, independent_forces.py).

Oracles are exact: closed forms or numerical quadrature of the linear oscillator's
spectra and impulse responses.  Statistical tolerances are stated in standard errors
(SE), computed from the same oracles, and refer to one fixed seed; the numbers quoted in
comments were measured on these records (``-m slow`` repeats the checks on 20
records each, to show the estimates are unbiased at a finer precision).
"""

import functools
import importlib
import itertools
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.signal
import scipy.stats

ANALYSES = Path(__file__).resolve().parents[1] / "analyses"
MODULES = ("independent_sim", "independent_forces")

#: Linear oscillator of the force checks: S_x = S_f / |a2 - w^2 + i a1 w|^2.
LINEAR = {"a1": 1.0, "n1": 0.0, "a2": 25.0, "n2": 0.0, "S0": 1.0}
NARROW = {"wf": 5.0, "zf": 0.1}  # the force's peak on the oscillator's resonance
DT = 0.05


@pytest.fixture(scope="module")
def sim():
    """The simulator module, imported with ``analyses/`` on the path (as the scripts run)."""
    sys.path.insert(0, str(ANALYSES))
    try:
        yield importlib.import_module("independent_sim")
    finally:
        sys.path.remove(str(ANALYSES))
        for name in MODULES:
            sys.modules.pop(name, None)


def _integral(f, peak=5.0):
    """``int_{-inf}^{inf} f`` of an even function peaked near ``peak``."""
    body = scipy.integrate.quad(f, 0.0, 50.0, points=[peak], limit=500, epsrel=1e-12)[0]
    return 2.0 * (body + scipy.integrate.quad(f, 50.0, np.inf, epsrel=1e-12)[0])


def _oscillator_gain(w):
    return 1.0 / ((LINEAR["a2"] - w**2) ** 2 + (LINEAR["a1"] * w) ** 2)


def _narrow_shape(w):
    wf, zf = NARROW["wf"], NARROW["zf"]
    return wf**4 / ((wf**2 - w**2) ** 2 + (2.0 * zf * wf * w) ** 2)


# --- no new key: the records of the code before wf, zf and rate ---------------------

PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}
#: x[0], x[-1], v[-1], sum x^2, sum v^2 of 400 s at dt = 0.02 (substeps 10, burn-in 20 s,
#: default_rng(123)), printed by the code before the change (bit-identical after it).
BEFORE = {
    "white": (
        {},
        (
            -0.6550989222807082,
            0.13064022411172993,
            -3.073884299699381,
            26392.24563000331,
            1057370.4905355144,
        ),
    ),
    "effects": (
        {"b2": 3.0, "mu": 0.7, "m": 2.0, "noise_sd": 0.1},
        (
            -0.5216864517741868,
            0.02746664128607562,
            -2.599367419372172,
            26577.282834955404,
            1045066.5733526524,
        ),
    ),
    "lowpass": (
        {"wc": 8.0},
        (
            -0.8160123129253626,
            -0.8955398059410234,
            5.717743172783483,
            24995.05788184089,
            629842.3451675763,
        ),
    ),
}


def _run_before(sim, extra):
    rec, v = sim.simulate(
        {**PAPER, **extra},
        duration=400.0,  # 21 000 samples: three noise chunks
        dt=0.02,
        rng=np.random.default_rng(123),
        substeps=10,
        burn_in=20.0,
    )
    return rec.x, v


@pytest.mark.parametrize("case", sorted(BEFORE))
def test_records_unchanged_without_the_new_keys(sim, case):
    extra, numbers = BEFORE[case]
    x, v = _run_before(sim, extra)
    got = (x[0], x[-1], v[-1], np.sum(x**2), np.sum(v**2))
    # bit-identical here; 1e-12 leaves room for another libm only (a changed random
    # stream or step moves every number at O(1))
    np.testing.assert_allclose(got, numbers, rtol=1e-12, atol=0)
    # the new keys at 0 are the same as absent
    x0, v0 = _run_before(sim, {**extra, "wf": 0.0, "zf": 0.0, "rate": 0.0})
    np.testing.assert_array_equal(x0, x)
    np.testing.assert_array_equal(v0, v)


# --- narrow-band force --------------------------------------------------------------


@pytest.mark.parametrize(
    ("wf", "zf", "h"), [(5.0, 0.1, DT / 40), (5.0, 0.1, 1e-6), (2.0, 0.7, 0.3)]
)
def test_narrowband_matrices_are_exact(sim, wf, zf, h):
    """Van Loan's covariance against quadrature, the Lyapunov solution against its closed
    form, and the stationary law kept by one step (relative 1e-9 entry by entry).
    """
    forces = sys.modules["independent_forces"]
    S0 = 2.0
    phi, cov, stat = forces.narrowband_matrices(wf, zf, S0, h)
    a = np.array([[0.0, 1.0, 0.0], [-(wf**2), -2.0 * zf * wf, 0.0], [1.0, 0.0, 0.0]])
    b = np.array([0.0, wf**2 * math.sqrt(2.0 * math.pi * S0), 0.0])
    np.testing.assert_allclose(phi, scipy.linalg.expm(a * h), rtol=1e-12, atol=1e-15)

    def integrand(s):
        eb = scipy.linalg.expm(a * s) @ b
        return np.outer(eb, eb)

    ref = scipy.integrate.quad_vec(integrand, 0.0, h, epsrel=1e-13, epsabs=0.0)[0]
    scale = np.sqrt(np.outer(np.diag(ref), np.diag(ref)))  # off-diagonals vs their scale
    assert np.max(np.abs(cov - ref) / scale) < 1e-9
    low = forces._factor(cov)
    assert np.max(np.abs(low @ low.T - cov) / scale) < 1e-12
    assert np.all(np.linalg.eigvalsh(cov / scale) > 0)  # rank 3, not 2

    # stationary (g, g'): var g = pi S0 wf / (2 zf), var g' = pi S0 wf^3 / (2 zf), uncorrelated
    var_g = math.pi * S0 * wf / (2.0 * zf)
    np.testing.assert_allclose(
        stat, np.diag([var_g, var_g * wf**2]), rtol=1e-10, atol=1e-10 * var_g
    )
    # one step from the stationary law: (g, g') keeps it, and the impulse I has
    # var I = 2 int_0^h (h - t) R_g(t) dt, R_g(t) = var_g e^{-zf wf t} (cos + zf wf/wd sin)(wd t)
    step = phi[:, :2] @ stat @ phi[:, :2].T + cov
    np.testing.assert_allclose(step[:2, :2], stat, rtol=1e-9, atol=1e-9 * var_g * wf)
    wd = wf * math.sqrt(1.0 - zf**2)

    def r_g(t):
        return (
            var_g * math.exp(-zf * wf * t) * (math.cos(wd * t) + zf * wf / wd * math.sin(wd * t))
        )

    var_i = 2.0 * scipy.integrate.quad(lambda t: (h - t) * r_g(t), 0.0, h, epsrel=1e-13)[0]
    assert step[2, 2] == pytest.approx(var_i, rel=1e-9)


def test_narrowband_force_starts_stationary(sim, monkeypatch):
    """The impulse over the first sub-step and over the 200th, across 2000 independent
    starts, has the stationary variance (SE sqrt(2/2000) = 3.2 %; tolerance 4 SE).  A start
    from g = g' = 0 would give 2.5e-6 of it for the first.
    """
    forces = sys.modules["independent_forces"]
    # the matrices once (scipy's expm takes ms), each start's draw as in the simulator
    monkeypatch.setattr(forces, "narrowband_matrices", functools.cache(forces.narrowband_matrices))
    wf, zf, S0, h = 5.0, 0.1, 1.0, 0.01
    phi, cov, stat = forces.narrowband_matrices(wf, zf, S0, h)
    var_i = (phi[2, :2] @ stat @ phi[2, :2] + cov[2, 2]) / h**2  # mean force over h
    rng = np.random.default_rng(5)
    first, last = [], []
    for _ in range(2000):
        imp = forces.NarrowBand(wf, zf, S0, h, rng).impulses(rng, 200)[0] / h
        first.append(imp[0])
        last.append(imp[-1])
    for sample in (first, last):
        ratio = np.mean(np.square(sample)) / var_i
        assert ratio == pytest.approx(1.0, abs=4 * math.sqrt(2 / 2000)), ratio


def _narrow_oracles():
    """``{name: (spectrum, int spectrum, int spectrum^2)}`` of x and v, narrow-band force."""

    def s_x(w):
        return LINEAR["S0"] * _narrow_shape(w) * _oscillator_gain(w)

    def s_v(w):
        return w**2 * s_x(w)

    return {
        name: (s, _integral(s), _integral(lambda w, s=s: s(w) ** 2))
        for name, s in (("x", s_x), ("v", s_v))
    }


def test_narrowband_linear_response(sim):
    """Linear oscillator (a1 = 1, a2 = 25, S0 = 1) under the narrow-band force (wf = 5,
    zf = 0.1), 4000 s at dt = 0.05.

    * Welch spectrum (2048-sample Hann segments, ~77 of them: ~12 % scatter a bin) over
      1 <= omega < 12 rad/s, where it spans five decades and leakage is negligible,
      against S0 L(omega) / ((a2 - omega^2)^2 + (a1 omega)^2): the mean ratio within 4 %
      (its sd over 40 records: 1.3 %), every bin within a factor 2 (extremes over 40
      records: 0.62, 1.54), and the means over 7 sub-bands of 1-20 rad/s within 15 %
      (sd <= 4.7 %).  Here: mean 1.0034, bins 0.72-1.25, sub-bands 0.957-1.026.
    * var(x) and E[v^2] against the quadrature of their spectra, within 4 SE; SE of a
      second moment of a Gaussian record: sqrt(4 pi int S^2 / T) (3.5 % for x).
      Here: var x 1.6446 vs 1.6336 (z = +0.19), E[v^2] 39.285 vs 39.270 (z = +0.01).
    """
    T = 4000.0
    rec, v = sim.simulate({**LINEAR, **NARROW}, duration=T, dt=DT, rng=np.random.default_rng(7))
    oracles = _narrow_oracles()
    f, p = scipy.signal.welch(rec.x, fs=1.0 / DT, nperseg=2048)
    w = 2.0 * np.pi * f
    ratio = p / (4.0 * np.pi) / oracles["x"][0](w)  # two-sided density in rad/s
    band = (w >= 1.0) & (w < 12.0)
    assert ratio[band].mean() == pytest.approx(1.0, abs=0.04)
    edges = (1.0, 3.0, 4.5, 5.5, 7.0, 9.0, 12.0, 20.0)
    for lo, hi in itertools.pairwise(edges):
        assert ratio[(w >= lo) & (w < hi)].mean() == pytest.approx(1.0, abs=0.15), (lo, hi)
    assert np.all((ratio[band] > 0.5) & (ratio[band] < 2.0))
    for name, y in (("x", rec.x), ("v", v)):
        _, second, square = oracles[name]
        se = math.sqrt(4.0 * math.pi * square / T)
        assert abs(np.mean(y**2) - second) < 4.0 * se, (name, np.mean(y**2), second, se)


# --- Poisson impulses ---------------------------------------------------------------


def _impulse_oracles(rate):
    """Exact stationary moments of the linear oscillator under Poisson impulses.

    v = sum_j A_j h_v(t - t_j) is filtered Poisson noise, so (Campbell) its cumulants are
    kappa_n(v) = rate E[A^n] int_0^inf h_v^n dt: kappa_2 = 2 pi S0 int h_v^2 = pi S0 / a1
    (any rate), and kappa_4 = rate 3 (2 pi S0 / rate)^2 int h_v^4, excess kurtosis
    kappa_4 / kappa_2^2; the same for x with h_x.  The SE of a record's mean square over T
    adds to the Gaussian 4 pi int S^2 the fourth cumulant's rate E[A^4] (int h^2)^2.
    """
    a1, a2, S0 = LINEAR["a1"], LINEAR["a2"], LINEAR["S0"]
    wd = math.sqrt(a2 - a1**2 / 4.0)

    def h_x(t):
        return math.exp(-a1 * t / 2.0) * math.sin(wd * t) / wd

    def h_v(t):
        return math.exp(-a1 * t / 2.0) * (math.cos(wd * t) - a1 / (2.0 * wd) * math.sin(wd * t))

    def power_integral(h, n):
        return scipy.integrate.quad(
            lambda t: h(t) ** n, 0.0, 60.0 / a1, limit=2000, epsabs=0.0, epsrel=1e-11
        )[0]

    ea4 = 3.0 * (2.0 * math.pi * S0 / rate) ** 2  # E[A^4], A ~ N(0, 2 pi S0 / rate)
    out = {}
    for name, h, k2, power in (
        ("x", h_x, math.pi * S0 / (a1 * a2), 0),
        ("v", h_v, math.pi * S0 / a1, 2),
    ):
        h2 = power_integral(h, 2)
        assert 2.0 * math.pi * S0 * h2 == pytest.approx(k2, rel=1e-9)
        square = _integral(lambda w, p=power: (S0 * w**p * _oscillator_gain(w)) ** 2)
        out[name] = {
            "k2": k2,
            "ek": rate * ea4 * power_integral(h, 4) / k2**2,
            "var_ms": 4.0 * math.pi * square + rate * ea4 * h2**2,
        }
    return out


def test_impulses_linear_moments_and_kurtosis(sim):
    """Linear oscillator (a1 = 1, a2 = 25, S0 = 1) under Poisson impulses, 40 000 s at
    dt = 0.05 for rates 0.5 and 50 per second.

    * E[v^2] = pi S0 / a1 and var(x) = pi S0 / (a1 a2) for any rate, within 4 SE (SE from
      the exact formula of ``_impulse_oracles``, checked against the scatter over 20
      records: 1.4 % at rate 0.5, 0.7 % at rate 50).
      Here: rate 0.5: E[v^2] 3.1555 (pi; z = +0.31), var x 0.12613 (0.12566, z = +0.26);
      rate 50: E[v^2] 3.1292 (z = -0.55), var x 0.12505 (z = -0.67).
    * Excess kurtosis of v and x against kappa_4 / kappa_2^2: within 10 % at rate 0.5
      (oracle 4.544 for v, 4.369 for x: clearly non-Gaussian; sd over records 2.5 %) and
      within 0.05 at rate 50 (oracle 0.045, 0.044; sd over records 0.014).
      Here: rate 0.5: 4.626 and 4.402; rate 50: 0.016 and 0.018.
    """
    T = 40000.0
    for rate, kurt_tol in ((0.5, ("rel", 0.10)), (50.0, ("abs", 0.05))):
        rec, v = sim.simulate(
            {**LINEAR, "rate": rate}, duration=T, dt=DT, rng=np.random.default_rng(11)
        )
        oracles = _impulse_oracles(rate)
        for name, y in (("x", rec.x - rec.x.mean()), ("v", v)):
            o = oracles[name]
            ms = np.mean(y**2)
            assert abs(ms - o["k2"]) < 4.0 * math.sqrt(o["var_ms"] / T), (rate, name, ms, o)
            ek = scipy.stats.kurtosis(y)
            kind, tol = kurt_tol
            bound = tol * o["ek"] if kind == "rel" else tol
            assert abs(ek - o["ek"]) < bound, (rate, name, ek, o["ek"])
        if rate < 1.0:
            assert scipy.stats.kurtosis(v) > 3.0  # visibly non-Gaussian


# --- bad input ----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("extra", "match"),
    [
        ({"wf": 5.0}, "both wf > 0 and zf > 0"),
        ({"zf": 0.1}, "both wf > 0 and zf > 0"),
        ({"wf": -5.0, "zf": 0.1}, "both wf > 0 and zf > 0"),
        ({"wf": 5.0, "zf": -0.1}, "both wf > 0 and zf > 0"),
        ({"wf": float("nan"), "zf": 0.1}, "must be finite"),
        ({"wf": 5.0, "zf": 0.1, "wc": 3.0}, "exclude each other"),
        ({"rate": -1.0}, r"rate \(Poisson impulses per second\) must be >= 0"),
        ({"rate": float("inf")}, "must be finite"),
        ({"rate": 2.0, "wc": 3.0}, "not with wc or wf"),
        ({"rate": 2.0, "wf": 5.0, "zf": 0.1}, "not with wc or wf"),
        ({"wn": 5.0}, r"unknown \['wn'\]"),
    ],
)
def test_bad_force_keys(sim, extra, match):
    with pytest.raises(ValueError, match=match):
        sim.simulate({**LINEAR, **extra}, duration=10.0, dt=DT, rng=np.random.default_rng(0))


def test_new_forces_are_seeded(sim):
    for extra in (NARROW, {"rate": 3.0}):
        a, va = sim.simulate(
            {**PAPER, **extra}, duration=200.0, dt=0.02, rng=np.random.default_rng(4)
        )
        b, vb = sim.simulate(
            {**PAPER, **extra}, duration=200.0, dt=0.02, rng=np.random.default_rng(4)
        )
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(va, vb)
        assert np.all(np.isfinite(a.x)) and a.x.size == 10000


def test_imported_by_path_without_analyses_on_sys_path(tmp_path):
    """hosid batch imports the simulator file by path (``analyses/`` not on ``sys.path``):
    it still finds ``independent_forces.py`` beside it.
    """
    path = str(ANALYSES / "independent_sim.py")
    code = (
        "import importlib.util, sys, numpy as np\n"
        f"spec = importlib.util.spec_from_file_location('independent_sim', {path!r})\n"
        "m = importlib.util.module_from_spec(spec); sys.modules['independent_sim'] = m\n"
        "spec.loader.exec_module(m)\n"
        "p = {'a1': 1.0, 'a2': 25.0, 'n1': 0.0, 'n2': 0.0, 'S0': 1.0, 'rate': 2.0}\n"
        "rec, v = m.simulate(p, duration=20.0, dt=0.05, rng=np.random.default_rng(0))\n"
        "print(rec.x.size, m.independent_forces.__file__)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["400", str(ANALYSES / "independent_forces.py")]


# --- slow: the same oracles at a finer precision ------------------------------------


@pytest.mark.slow
def test_new_forces_unbiased_over_records(sim):
    """20 records each: narrow-band var(x), E[v^2] and Welch band ratios, and at rate 2
    the impulse-driven E[v^2], var(x) and excess kurtosis, each mean over records within
    3.5 SE of its oracle (SE from the scatter over records).
    """
    n = 20
    oracles = _narrow_oracles()
    rows = []
    for k in range(n):
        rec, v = sim.simulate(
            {**LINEAR, **NARROW}, duration=4000.0, dt=DT, rng=np.random.default_rng(100 + k)
        )
        f, p = scipy.signal.welch(rec.x, fs=1.0 / DT, nperseg=2048)
        w = 2.0 * np.pi * f
        band = (w >= 1.0) & (w < 12.0)
        ratio = (p / (4.0 * np.pi) / oracles["x"][0](w))[band].mean()
        rows.append((np.mean(rec.x**2) / oracles["x"][1], np.mean(v**2) / oracles["v"][1], ratio))
    _assert_unbiased(np.array(rows), np.ones(3))

    rate = 2.0
    o = _impulse_oracles(rate)
    rows = []
    for k in range(n):
        rec, v = sim.simulate(
            {**LINEAR, "rate": rate}, duration=40000.0, dt=DT, rng=np.random.default_rng(200 + k)
        )
        x = rec.x - rec.x.mean()
        rows.append(
            (np.mean(v**2), np.mean(x**2), scipy.stats.kurtosis(v), scipy.stats.kurtosis(x))
        )
    truth = [o["v"]["k2"], o["x"]["k2"], o["v"]["ek"], o["x"]["ek"]]
    _assert_unbiased(np.array(rows), np.array(truth))


def _assert_unbiased(rows, truth):
    mean = rows.mean(axis=0)
    se = rows.std(axis=0, ddof=1) / math.sqrt(rows.shape[0])
    assert np.all(np.abs(mean - truth) < 3.5 * se), (mean, truth, se)

"""Named changes in monitor tracks (:mod:`hosid.monitor.changes`).

Oracles: the share of a window after a step, by numerical integration of the step over
the window (tolerance: the midpoint rule's 1/N); the GLS estimates against a direct
generalized least-squares solve (1e-9); the false-alarm rate of tracks without change
(white window errors, and 50 %-overlapping windows that are means of a white sequence,
so that the overlap correlation is exact) inside a binomial 99 % band around alpha;
detection, time- and size-interval coverage of a 3-sigma step inside binomial 99 % bands
around their levels; a noise-free step located to the grid spacing.  Every Monte-Carlo
draw comes from a seeded Generator, so each assertion refers to one fixed realization.
"""

import numpy as np
import pytest
from scipy import stats

from hosid.errors import HosidInputError
from hosid.monitor.changes import (
    all_changes,
    find_changes,
    overlap_correlation,
    profile,
    scan,
    share_after,
    tau_grid,
)


def band(reps, p, conf=0.99):
    """Binomial ``conf`` band of a count out of ``reps`` at rate ``p``."""
    return stats.binom.interval(conf, reps, p)


def windows(n, length=10.0, step=10.0):
    s = np.arange(n) * step
    return s, s + length


def overlap_noise(rng, n):
    """Means of 50 %-overlapping windows of a white sequence, unit variance: the
    half-window block sums are iid, so the adjacent correlation is exactly 0.5."""
    b = rng.standard_normal(n + 1)
    return (b[:-1] + b[1:]) / np.sqrt(2.0)


def test_share_after_by_hand():
    s, e = np.array([0.0, 5.0, 20.0]), np.array([10.0, 15.0, 24.0])
    tau = np.array([-1.0, 0.0, 2.5, 7.5, 10.0, 21.0, 30.0])
    f = share_after(s, e, tau)
    assert f.shape == (3, 7)
    by_hand = [
        [1.0, 1.0, 0.75, 0.25, 0.0, 0.0, 0.0],
        [1.0, 1.0, 1.0, 0.75, 0.5, 0.0, 0.0],
        [1.0, 1.0, 1.0, 1.0, 1.0, 0.75, 0.0],
    ]
    np.testing.assert_allclose(f, by_hand, atol=1e-15)
    # f_i = (1 / len_i) * integral over the window of the indicator t >= tau (midpoint rule)
    n = 100_000
    for si, ei in zip(s, e, strict=True):
        t = si + (np.arange(n) + 0.5) * (ei - si) / n
        integral = [(t >= x).mean() for x in tau]
        np.testing.assert_allclose(share_after([si], [ei], tau)[0], integral, atol=1.0 / n)


def test_overlap_correlation_by_hand():
    rho = overlap_correlation([0.0, 5.0, 5.0, 30.0], [10.0, 15.0, 25.0, 40.0])
    assert rho[0, 1] == pytest.approx(0.5, abs=1e-15)
    assert rho[0, 2] == pytest.approx(5.0 / np.sqrt(200.0), abs=1e-15)
    assert rho[1, 2] == pytest.approx(10.0 / np.sqrt(200.0), abs=1e-15)
    assert rho[0, 3] == 0.0
    np.testing.assert_allclose(np.diag(rho), 1.0)


@pytest.mark.parametrize("step", [10.0, 5.0])
def test_profile_is_the_direct_gls(step):
    rng = np.random.default_rng(1)
    n, nugget, base = 25, 0.1, (0.3, 0.5)
    s, e = windows(n, step=step)
    sd = rng.uniform(0.5, 2.0, n)
    y = rng.standard_normal(n) * sd + 2.0 * share_after(s, e, 0.6 * s[-1])
    tau = tau_grid(s, e, e[1], s[-2])
    prof = profile(s, e, y, sd, tau, baseline=base, nugget=nugget)
    rho = (1 - nugget) * overlap_correlation(s, e) + nugget * np.eye(n)
    sig = np.append(sd, base[1])
    cov = np.pad(rho, ((0, 1), (0, 1))) * np.outer(sig, sig)
    cov[n, n] = base[1] ** 2
    w = np.linalg.inv(cov)
    yy = np.append(y, base[0])
    for j in range(0, tau.size, 17):
        x = np.column_stack([np.ones(n + 1), np.append(share_after(s, e, tau[j]), 0.0)])
        c = np.linalg.inv(x.T @ w @ x)
        mu, delta = c @ x.T @ w @ yy
        assert prof.size[j] == pytest.approx(delta, rel=1e-9, abs=1e-9)
        assert prof.before[j] == pytest.approx(mu, rel=1e-9, abs=1e-9)
        assert prof.size_se[j] == pytest.approx(np.sqrt(c[1, 1]), rel=1e-9)
        assert prof.statistic[j] == pytest.approx(delta**2 / c[1, 1], rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("layout", ["separate", "overlap"])
def test_false_alarm_rate_without_change(layout):
    """Exact model (nugget 0): the Monte-Carlo test has level exactly alpha
    (alpha * (draws + 1) = 10 is whole), so the rate over 400 tracks lies in the
    binomial 99 % band around 0.05 (2000 tracks of 30 windows: 0.049 separate, 0.055
    overlapping)."""
    rng = np.random.default_rng(20260201 + (layout == "overlap"))
    n, reps = 16, 400
    s, e = windows(n, step=10.0 if layout == "separate" else 5.0)
    alarms = 0
    for _ in range(reps):
        sd = rng.uniform(0.5, 2.0, n)
        eps = rng.standard_normal(n) if layout == "separate" else overlap_noise(rng, n)
        sc = scan(s, e, 2.0 + eps * sd, sd, rng=rng, nugget=0.0, draws=199)
        alarms += bool(sc.changes)
    lo, hi = band(reps, 0.05)
    assert lo <= alarms <= hi


def test_default_nugget_is_conservative_on_exact_overlap():
    rng = np.random.default_rng(20260203)
    n, reps = 16, 400
    s, e = windows(n, step=5.0)
    alarms = sum(
        bool(scan(s, e, overlap_noise(rng, n), np.ones(n), rng=rng, draws=199).changes)
        for _ in range(reps)
    )
    assert alarms <= band(reps, 0.05)[1]


@pytest.fixture(scope="module")
def step_runs():
    """200 tracks of 40 windows with a 3-sigma step at a random point inside window 20."""
    rng = np.random.default_rng(20260204)
    n, reps, delta = 40, 200, 3.0
    s, e = windows(n)
    runs = []
    for _ in range(reps):
        tau = rng.uniform(s[20] + 0.5, e[20] - 0.5)
        y = 1.0 + rng.standard_normal(n) + delta * share_after(s, e, tau)
        runs.append((tau, scan(s, e, y, np.ones(n), rng=rng, draws=399)))
    return s, e, delta, runs


def test_step_is_named(step_runs):
    _, _, _, runs = step_runs
    named = sum(bool(sc.changes) for _, sc in runs)
    assert named >= len(runs) - 2  # T ~ 90 against a threshold ~ 12


def test_time_and_size_intervals_cover(step_runs):
    """Here 183 and 191 of 200; measured over 1000 tracks: 0.942 and 0.959."""
    _, _, delta, runs = step_runs
    hits_t = hits_s = count = 0
    for tau, sc in runs:
        if not sc.changes:
            continue
        c = min(sc.changes, key=lambda c: abs(c.time - tau))
        assert c.time_lo <= c.time <= c.time_hi and c.size_lo <= c.size <= c.size_hi
        hits_t += c.time_lo <= tau <= c.time_hi
        hits_s += c.size_lo <= delta <= c.size_hi
        count += 1
    lo, hi = band(count, 0.95)
    assert lo <= hits_t <= hi
    assert lo <= hits_s <= hi


def test_interior_change_is_located_in_its_window():
    s, e = windows(30)
    tau = s[14] + 3.7
    y = 1.0 + 2.0 * share_after(s, e, tau)  # noise-free: the argmax is the true time
    sc = scan(s, e, y, np.ones(30), rng=np.random.default_rng(5), draws=199)
    (c,) = sc.changes
    assert abs(c.time - tau) <= 10.0 / 20  # one grid spacing
    # off the grid by < 0.25 s = 0.025 of the window: size and level within 2 * 0.025
    assert c.size == pytest.approx(2.0, abs=0.05) and c.before == pytest.approx(1.0, abs=0.05)
    # with noise the window's own error moves tau_hat: measured inside the window in 0.88
    # of 500 tracks at 6 sigma (0.95 at 10, 0.66-0.72 at 3); binomial 99 % band at 0.88
    rng = np.random.default_rng(20260205)
    inside = 0
    for _ in range(100):
        t0 = rng.uniform(s[14] + 1.0, e[14] - 1.0)
        y = rng.standard_normal(30) + 6.0 * share_after(s, e, t0)
        found = scan(s, e, y, np.ones(30), rng=rng, draws=199).changes
        c = min(found, key=lambda c: abs(c.time - t0))
        inside += s[14] <= c.time <= e[14]
    assert inside >= band(100, 0.88)[0]


def test_baseline_enters_before_the_first_window():
    rng = np.random.default_rng(7)
    n = 12
    s, e = windows(n)
    y = rng.standard_normal(n) * 0.5
    sd = np.full(n, 0.5)
    assert not scan(s, e, y, sd, rng=rng, draws=399).changes
    assert not scan(s, e, y, sd, rng=rng, baseline=(y.mean(), 0.2), draws=399).changes
    (c,) = scan(s, e, y, sd, rng=rng, baseline=(3.0, 0.2), draws=399).changes
    # the whole record differs from the reference: the change is at its start
    assert s[0] == c.time_lo <= c.time <= e[0]
    assert c.size_lo <= y.mean() - 3.0 <= c.size_hi
    assert c.before == pytest.approx(3.0, abs=0.5)


def test_baseline_windows_keep_the_change_after_them():
    rng = np.random.default_rng(8)
    n, k = 20, 6
    s, e = windows(n)
    y = rng.standard_normal(n) + 4.0 * share_after(s, e, 103.0)
    sc = scan(s, e, y, np.ones(n), rng=rng, baseline_windows=k, draws=399)
    (c,) = sc.changes
    assert c.time_lo >= e[k - 1] and s[9] <= c.time <= e[11]
    y = rng.standard_normal(n) + 4.0 * share_after(s, e, 33.0)  # inside the reference
    for c in scan(s, e, y, np.ones(n), rng=rng, baseline_windows=k, draws=399).changes:
        assert c.time_lo >= e[k - 1]


def test_failed_windows_are_dropped():
    rng = np.random.default_rng(9)
    n = 30
    s, e = windows(n)
    y = rng.standard_normal(n) + 3.0 * share_after(s, e, 152.0)
    sd = np.ones(n)
    y_nan, sd_nan = y.copy(), sd.copy()
    y_nan[[3, 17]] = np.nan
    sd_nan[22] = np.nan
    keep = np.setdiff1d(np.arange(n), [3, 17, 22])
    a = scan(s, e, y_nan, sd_nan, rng=np.random.default_rng(1), draws=399)
    b = scan(s[keep], e[keep], y[keep], sd[keep], rng=np.random.default_rng(1), draws=399)
    assert a.windows == n - 3 and a == b and len(a.changes) >= 1


def test_too_few_windows_give_no_test_and_a_reason():
    s, e = windows(6)
    y = np.array([0.0, 0.1, np.nan, np.nan, np.nan, 5.1])
    sc = scan(s, e, y, np.ones(6), rng=np.random.default_rng(0))
    assert sc.changes == () and sc.windows == 3
    assert sc.reason == "3 usable windows of 6; a scan needs 4"
    sc = scan(s[:3], e[:3], y[:3], np.ones(3), rng=np.random.default_rng(0))
    assert sc.changes == () and sc.reason is not None
    # enough windows, but at 75 % overlap none lies wholly between the first two and last two
    s, e = windows(5, step=2.5)
    sc = scan(s, e, np.zeros(5), np.ones(5), rng=np.random.default_rng(0))
    assert sc.changes == () and "no admissible change time" in sc.reason


@pytest.mark.parametrize("second", [4.0, -4.0])
def test_two_changes_are_both_found(second):
    rng = np.random.default_rng(20260206 + (second < 0))
    n = 60
    s, e = windows(n)
    t1, t2 = 203.0, 404.0
    both = 0
    for _ in range(20):
        y = rng.standard_normal(n) + 4.0 * share_after(s, e, t1) + second * share_after(s, e, t2)
        sc = scan(s, e, y, np.ones(n), rng=rng, draws=399)
        found = [any(c.time_lo - 10 <= t <= c.time_hi + 10 for c in sc.changes) for t in (t1, t2)]
        both += all(found)
    assert both >= 18


def test_find_changes_bonferroni():
    rng = np.random.default_rng(10)
    n = 30
    s, e = windows(n)
    tracks = {
        "a1": (rng.standard_normal(n) + 4.0 * share_after(s, e, 155.0), np.ones(n)),
        "S0": (rng.standard_normal(n), np.ones(n)),
        "a2": (np.full(n, np.nan), np.ones(n)),
    }
    scans = find_changes(tracks, s, e, rng=rng, alpha=0.06, draws=999)
    assert list(scans) == ["a1", "S0", "a2"]
    assert all_changes(scans) == list(scans["a1"].changes)
    assert all(sc.alpha == pytest.approx(0.02) for sc in scans.values())
    assert len(scans["a1"].changes) == 1 and scans["a1"].changes[0].parameter == "a1"
    c = scans["a1"].changes[0]
    assert c.p_value <= 0.02 and c.statistic > c.threshold
    assert scans["a2"].reason is not None and scans["S0"].reason is None
    assert 0.5 < scans["S0"].dispersion < 1.6  # chi2_29 / 29, 99.9 % range
    one = find_changes({"S0": tracks["S0"]}, s, e, rng=rng, family=4, draws=999)
    assert one["S0"].alpha == pytest.approx(0.0125)


def test_bad_settings_are_refused():
    s, e = windows(10)
    with pytest.raises(HosidInputError, match="cannot reach"):
        scan(s, e, np.zeros(10), np.ones(10), rng=np.random.default_rng(0), family=10, draws=99)
    with pytest.raises(HosidInputError, match="sd must be positive"):
        scan(s, e, np.zeros(10), np.zeros(10), rng=np.random.default_rng(0))
    with pytest.raises(HosidInputError, match="increasing"):
        scan(s[::-1], e[::-1], np.zeros(10), np.ones(10), rng=np.random.default_rng(0))

"""Likelihood components: estimating equations with mean ~0 at the truth, their shapes,
the Gaussian null of the trispectral ordinates."""

import math

import numpy as np
import pytest

from hosid.components import J2, Identities, Moments
from hosid.components.base import u_pseudovalues
from hosid.components.polyspectral import J4, null_variance
from hosid.model import PAPER_PARAMS, Model, simulate_ensemble
from hosid.spectra import BlockLayout, block_fft, get_window
from hosid.state import RecordState, velocity_deficit

PAPER = Model.from_spec("paper")
TRUTH = PAPER.vector(PAPER_PARAMS)

COMPONENTS = {
    "identities": Identities(),
    "restoring identities": Identities("restoring"),
    "J2": J2(),
    "J2 printed": J2(form="printed"),
    "J4A": J4("A"),
    "J4B": J4("B"),
}
LABELS = {
    "identities": ("identity a1", "identity n1", "identity a2", "identity n2"),
    "restoring identities": ("identity a2", "identity n2"),
    "J2": ("J2 d/da1", "J2 d/dn1", "J2 d/da2", "J2 d/dn2", "J2 d/dS0"),
    "J2 printed": ("J2 d/da1", "J2 d/dn1", "J2 d/da2", "J2 d/dn2", "J2 d/dS0"),
    "J4A": ("J4A d/da1", "J4A d/dn1", "J4A d/dS0"),
    "J4B": ("J4B d/da1", "J4B d/dn1"),
}


@pytest.fixture(scope="module")
def paper_state(paper_record):
    return RecordState.from_record(paper_record)


@pytest.fixture(scope="module")
def prepared(paper_state):
    return {name: c.prepare(paper_state, PAPER, TRUTH) for name, c in COMPONENTS.items()}


# ------------------------------------------------------------------ shapes
@pytest.mark.parametrize("name", list(COMPONENTS))
def test_moments_shapes_and_labels(prepared, name):
    m = prepared[name]
    assert isinstance(m, Moments)
    assert m.component == COMPONENTS[name].name
    assert m.labels == LABELS[name]
    assert m.k == len(m.labels)
    assert m.influence.shape == (97, m.k)  # (B, k)
    np.testing.assert_allclose(
        m.influence.mean(axis=0), 0.0, atol=1e-12 * np.abs(m.influence).max()
    )
    assert m.mean(TRUTH).shape == (m.k,)
    assert isinstance(m.info, dict)


@pytest.mark.parametrize("name", list(COMPONENTS))
def test_mean_vectorizes_over_parameter_sets(prepared, name):
    m = prepared[name]
    rng = np.random.default_rng(1)
    th = TRUTH * (1 + 0.1 * rng.standard_normal((3, 2, TRUTH.size)))
    batch = m.mean(th)
    assert batch.shape == (3, 2, m.k)
    loop = np.array([[m.mean(th[i, j]) for j in range(2)] for i in range(3)])
    np.testing.assert_allclose(batch, loop, rtol=1e-10, atol=1e-12 * np.abs(loop).max())


def test_identities_are_affine_in_theta(prepared):
    m = prepared["identities"]
    a, b = TRUTH, TRUTH * np.array([1.3, 0.7, 1.1, 0.9, 1.2])
    np.testing.assert_allclose(m.mean(0.25 * a + 0.75 * b), 0.25 * m.mean(a) + 0.75 * m.mean(b))
    s2 = m.info["velocity_restoration_s2"]
    assert s2 == pytest.approx(float(velocity_deficit(PAPER_PARAMS["S0"], 0.02)), rel=1e-12)


def test_spectral_components_see_the_whole_parameter_vector(prepared):
    # J4 gives equations along the damping (and S0) only, but its force is evaluated at
    # the whole theta: the stiffness's uncertainty reaches the damping (no plug-in)
    other = TRUTH.copy()
    other[2:4] *= [1.2, 0.8]
    for name in ("J2", "J4A", "J4B"):
        assert not np.allclose(prepared[name].mean(other), prepared[name].mean(TRUTH))
    # J4B needs no S0 (eqs 37-38)
    scaled = TRUTH.copy()
    scaled[4] *= 2
    np.testing.assert_allclose(prepared["J4B"].mean(scaled), prepared["J4B"].mean(TRUTH))


def test_component_info(prepared):
    assert prepared["J4A"].info["triples"] > 1000
    assert prepared["J4A"].info["domain"] == "principal"
    lo, hi = prepared["J2"].info["band_rad_s"]
    assert lo == pytest.approx(2 * 2 * math.pi / 20.48)  # bin 2: Hann leaks a mean into 0, 1
    assert hi <= 6 * 7.3 / 1.14  # 6 w_n


def test_bad_component_settings(paper_state):
    with pytest.raises(ValueError, match="unknown form"):
        J2(form="odd").prepare(paper_state, PAPER, TRUTH)
    with pytest.raises(ValueError, match="fewer than 3 bins"):
        J2(band=(0.0, 0.5)).prepare(paper_state, PAPER, TRUTH)
    with pytest.raises(ValueError, match="unknown J4 kind"):
        J4(kind="C").prepare(paper_state, PAPER, TRUTH)
    with pytest.raises(ValueError, match="unknown J4 reference"):
        J4(kind="B", reference="model").prepare(paper_state, PAPER, TRUTH)
    with pytest.raises(ValueError, match="unknown identity set"):
        Identities("some").prepare(paper_state, PAPER, TRUTH)
    with pytest.raises(ValueError, match="holds < 3 bins"):
        J4(omega_max=0.5).prepare(paper_state, PAPER, TRUTH)


# ------------------------------------------------------------------ jackknife of U-statistics
def _u_brute(d, e, blocks):
    idx = list(blocks)
    total = sum(
        np.real(np.einsum("tj,t->j", np.conj(d[r2]), e[r])) for r in idx for r2 in idx if r != r2
    )
    return total / (len(idx) * (len(idx) - 1))


def test_u_pseudovalues_are_the_delete_one_block_jackknife():
    rng = np.random.default_rng(0)
    B, n, J = 7, 5, 2
    d = rng.normal(size=(B, n, J)) + 1j * rng.normal(size=(B, n, J))
    e = rng.normal(size=(B, n)) + 1j * rng.normal(size=(B, n))
    full = _u_brute(d, e, range(B))
    brute = np.array(
        [B * full - (B - 1) * _u_brute(d, e, [r for r in range(B) if r != b]) for b in range(B)]
    )
    psi = u_pseudovalues(d, e)
    np.testing.assert_allclose(psi, brute, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(psi.mean(axis=0), full, rtol=1e-12)  # they average to U
    # weights equal in every block: no degenerate part, the pseudo-values are the
    # projection Re sum_t d* e_b (real weights and residuals too)
    same = np.broadcast_to(d[:1], d.shape)
    np.testing.assert_allclose(
        u_pseudovalues(same, e), np.real(np.einsum("tj,bt->bj", np.conj(d[0]), e)), rtol=1e-12
    )
    np.testing.assert_allclose(
        u_pseudovalues(d.real, e.real).mean(axis=0), _u_brute(d.real, e.real, range(B))
    )


# ------------------------------------------------------------------ mean zero at the truth
N_RECORDS = 24


@pytest.fixture(scope="module")
def z_scores():
    """z = mean(theta_true) / (influence sd / sqrt(B)) per record and equation, over 24
    paper records of 1000 s (48 blocks each); ~10 s (J4A and J4B take most)."""
    records = simulate_ensemble(
        PAPER_PARAMS, N_RECORDS, rng=np.random.default_rng(20260201), duration=1000.0
    )
    comps = {
        "identities": Identities(),
        "J2": J2(),
        "J4A": J4("A"),
        "J4B": J4("B"),
        "J4B bins": J4("B", reference="bins"),
    }
    z = {k: [] for k in comps}
    for rec in records:
        state = RecordState.from_record(rec)
        for name, c in comps.items():
            m = c.prepare(state, PAPER, TRUTH)
            B = m.influence.shape[0]
            z[name].append(m.mean(TRUTH) / (m.influence.std(axis=0, ddof=1) / math.sqrt(B)))
    return {k: np.array(v) for k, v in z.items()}


@pytest.mark.parametrize("name", ["identities", "J2", "J4A"])
def test_estimating_equations_have_mean_zero_at_the_truth(z_scores, name):
    z = z_scores[name]
    assert z.shape[0] == N_RECORDS
    # 24 records: the mean of z has sd ~0.2 (equations of one record are correlated, so
    # the pooled values are worth ~24-50 draws), the pooled sd ~0.15. Measured on this
    # seed: identities +0.03 +- 0.99, J2 -0.07 +- 0.91, J4A -0.14 +- 1.02. With 12 records
    # (13 seed sets) the mean ranged -0.58..+0.19 and the sd 0.60..1.48, so 12 records
    # would make the bounds ~2 sd wide.
    assert abs(z.mean()) < 0.6
    assert 0.7 < z.std(ddof=1) < 1.4


def test_J4B_has_mean_zero_at_the_truth_with_its_exact_reference(z_scores):
    # The Gaussian part formed from the blocks' covariances over distinct blocks
    # (hosid.components.gaussian_reference): measured -0.08 +- 0.63 on this seed. The
    # jackknife overstates this statistic's variance (its degenerate parts and those of
    # the Gaussian part cancel in the statistic, not in the pseudo-values), so the sd is
    # below one: J4B is weighted conservatively.
    z = z_scores["J4B"]
    assert z.shape == (N_RECORDS, 2)
    assert abs(z.mean()) < 0.4
    assert 0.4 < z.std(ddof=1) < 1.2


def test_J4B_with_the_bin_value_reference_is_biased_at_the_truth(z_scores):
    # eq 63's bin values with the mean weights: the weights and the record's own spectrum
    # come from the same blocks, and the equations sit below zero at the truth (measured
    # -1.62 +- 0.56 on this seed). Recorded here, not required: the known bias.
    z = z_scores["J4B bins"]
    assert z.shape == (N_RECORDS, 2)
    assert z.mean() < -1.0


# ------------------------------------------------------------------ Gaussian null of J4
def test_null_variance_of_independent_ordinates_is_one():
    # boxcar: rho(k) = 1 at 0 only; off the planes only the pairing (k_i, -k_i) survives
    trip = np.array([[9, 5, -3, 11], [8, 4, -5, 7]])
    got = null_variance(trip, lambda k: (np.asarray(k) == 0).astype(float))
    np.testing.assert_allclose(got, 1.0, rtol=1e-14)
    # on the plane k2 + k3 = 0: z1 z2 z3 z4* = z1 z1* |z2|^2: E = 1, E|.|^2 = 2 * 2
    on = null_variance(np.array([[7, 6, -6, 7]]), lambda k: (np.asarray(k) == 0).astype(float))
    assert on[0] == pytest.approx(4.0 - 1.0)


def test_null_variance_matches_hann_block_products():
    """Monte Carlo: 20 000 Hann blocks of white noise; z = Y / (dt sqrt(M k2)) has
    E[z(a) z(b)] = rho(a + b) on signed bins."""
    M, B = 64, 20_000
    win = get_window("hann")
    y = np.random.default_rng(3).standard_normal(M * B)
    z = block_fft(y, BlockLayout(M=M, B=B, dt=1.0), win) / math.sqrt(M * win.k2)

    def zk(k):
        return z[:, k] if k >= 0 else np.conj(z[:, -k])

    trip = np.array([[9, 5, -3, 11], [7, 6, -6, 7], [8, 4, -5, 7], [6, 6, -2, 10]])
    nv = null_variance(trip, lambda k: win.rho(k, M))
    for t, v in zip(trip, nv, strict=True):
        p = zk(t[0]) * zk(t[1]) * zk(t[2]) * np.conj(zk(t[3]))
        gauss = sum(win.rho(t[a] + t[b], M) ** 2 for a, b in ((0, 1), (0, 2), (1, 2)))
        # the mean is the Gaussian trispectrum (eq 36); sd of the mean <= 0.023
        assert p.mean().real == pytest.approx(gauss, abs=0.1)
        # sd of a variance estimate of 20 000 products: ~3 % off the planes, ~6 % on them;
        # measured deviations 1.9 %, 5.6 %, 2.0 %, 2.8 %
        assert np.var(p) == pytest.approx(v, rel=0.15)


# ------------------------------------------------------------------ force kurtosis
def _excess(g: np.ndarray) -> float:
    """The blocks' excess kurtosis of ``g`` ``(B, M)``: the fourth moment less three
    times the U-statistic of the squared variance, over it.
    """
    m2 = (g**2).mean(axis=1)
    B = m2.size
    cross = (m2.sum() ** 2 - np.sum(m2**2)) / (B * (B - 1))
    return float(((g**4).mean() - 3.0 * cross) / cross)


def test_force_kurtosis_is_the_excess_kurtosis_in_the_forces_own_scale(paper_state):
    # away from the pilot too (its weight is the pilot's, its scale the force's own): the
    # inferred force on the blocks at theta, its excess kurtosis computed directly
    from hosid.components import ForceKurtosis
    from hosid.components.base import restoration

    m = ForceKurtosis().prepare(paper_state, PAPER, TRUTH)
    s2, eps = restoration(paper_state, PAPER, TRUTH)
    blk = paper_state.blocks
    phi = [
        t.smoothed(blk["v"], s2, eps) if t.variable == "v" else t.phi(blk["x"])
        for t in PAPER.drift_terms
    ]
    rng = np.random.default_rng(3)
    for theta in TRUTH * (1.0 + 0.3 * rng.standard_normal((3, TRUTH.size))):
        g = blk["a"] + sum(c * f for c, f in zip(theta, phi, strict=False))
        np.testing.assert_allclose(m.mean(theta)[0], _excess(g), rtol=1e-9)


def test_chain_kurtosis_of_a_chain_is_each_dofs_excess_kurtosis():
    # the chains' path (not the single oscillator's arithmetic): random block features
    # of each dof of a 2-dof chain, its inferred force X = Y lambda(theta), X's excess
    # kurtosis directly; the same force in another scale has the same equation
    from hosid.components.chain_cumulant import _kurtosis
    from hosid.components.chain_features import lam
    from hosid.model.system import System

    system = System(
        ("x1", "x2"),
        [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))],
        values={
            "a1[ground-x1]": 1.0, "a2[ground-x1]": 25.0, "a1[x1-x2]": 0.5,
            "a2[x1-x2]": 15.0, "mass[x2]": 0.5, "S0[x1]": 10.0, "S0[x2]": 5.0,
        },
    )  # fmt: skip
    rng = np.random.default_rng(4)
    th0 = system.vector()
    for d in range(2):
        F = lam(system, th0, d).size
        Y = rng.standard_normal((12, 400, F)) * rng.uniform(0.5, 2.0, F)
        Y[..., 0] += rng.standard_t(5, (12, 400))  # a non-Gaussian part
        mean = _kurtosis(Y, system, d, th0)[0]
        for theta in th0 * (1.0 + 0.3 * rng.standard_normal((2, th0.size))):
            np.testing.assert_allclose(mean(theta)[0], _excess(Y @ lam(system, theta, d)),
                                       rtol=1e-9)  # fmt: skip
        scaled = _kurtosis(2.5 * Y, system, d, th0)[0]
        np.testing.assert_allclose(scaled(th0), mean(th0), rtol=1e-9)

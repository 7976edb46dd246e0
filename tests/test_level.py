"""The level component (:mod:`hosid.components.level`) and the default set around it.

Oracles: the alias sum at the Nyquist frequency in closed form (the odd reciprocal
fourth powers, pi^4/96); the equation's expectation 0 at the true parameters over
replicated records (tolerance 3 standard errors of the mean over the records); which
blocks touch a segment's ends, counted by hand.
"""

import math

import numpy as np
import pytest

import hosid
from hosid.components.level import GUARD, Level, alias_factor, end_blocks
from hosid.inference.estimate import components_for, prepare_state
from hosid.model import Model

PAPER = {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 100.0}


def test_alias_factor_closed_forms():
    wn = 10.0
    # at the Nyquist frequency: sum over all j of (1 / (1 + 2 j))^4 = 2 * pi^4 / 96
    assert alias_factor(np.array([wn]), wn)[0] == pytest.approx(math.pi**4 / 48, rel=1e-6)
    assert alias_factor(np.array([1e-3]), wn)[0] == pytest.approx(1.0, abs=1e-12)
    a = alias_factor(np.linspace(0.1, wn, 50), wn)
    assert np.all(np.diff(a) > 0)


def test_end_blocks_touch_every_segment_end():
    rec = hosid.simulate(PAPER, duration=400.0, dt=0.02, rng=np.random.default_rng(1))
    two = hosid.Record.from_segments([rec.x, rec.x[::-1] * 0.9], rec.dt)
    for r in (rec, two):
        state = prepare_state(r, Model.from_spec("paper"))
        ends = end_blocks(state)
        first = state.layout.offsets
        last = first + state.layout.M - 1
        for b, (f, l_) in enumerate(zip(first, last, strict=True)):
            touches = any(
                (f < a + GUARD and l_ >= a) or (l_ > e - 1 - GUARD and f <= e - 1)
                for a, e in r.bounds
            )
            assert ends[b] == touches
        assert ends[0]
        assert ends.sum() <= 2 * len(r.bounds)


def test_level_equation_vanishes_at_the_truth():
    model = Model.from_spec("paper")
    theta = np.array([PAPER[p] for p in model.param_names])
    values = []
    for seed in range(8):
        rec = hosid.simulate(PAPER, duration=600.0, dt=0.02, rng=np.random.default_rng(seed))
        m = Level().prepare(prepare_state(rec, model), model, theta)
        assert m.labels == ("level S0",)
        values.append(float(m.mean(theta)[0]))
    values = np.array(values)
    se = values.std(ddof=1) / math.sqrt(values.size)
    assert abs(values.mean()) < 3 * se + 1e-3  # measured: 0.08 % over 40 longer records
    assert values.std() < 0.03  # about 1 / sqrt(bins x blocks)


def test_default_set_takes_the_level_for_a_white_force_only():
    rec = hosid.simulate(PAPER, duration=600.0, dt=0.02, rng=np.random.default_rng(3))
    white = hosid.estimate(rec, "paper")
    labels = [lab for m in white.ql.moments for lab in m.labels]
    assert "level S0" in labels and [lab for lab in labels if lab.startswith("J2")] == ["J2 d/dS0"]
    assert white.test["df"] >= 2  # Hansen's test keeps its degrees of freedom
    assert any(isinstance(c, Level) for c in components_for())
    coloured = hosid.estimate(rec, "paper,coloured_excitation")
    labels = [lab for m in coloured.ql.moments for lab in m.labels]
    assert "level S0" not in labels and "J2 d/da1" in labels
    # a J2 band the user chose is kept
    band = hosid.estimate(rec, "paper", components_for(band=(0.0, 20.0)))
    labels = [lab for m in band.ql.moments for lab in m.labels]
    assert "J2 d/da1" in labels


def test_level_stands_aside_when_every_block_touches_a_segment_end():
    rec = hosid.simulate(PAPER, duration=600.0, dt=0.02, rng=np.random.default_rng(4))
    model = Model.from_spec("paper")
    M = 256  # one block a segment, at the segment's start
    pieces = [rec.x[i : i + M + M // 2] for i in range(0, rec.n - 2 * M, M + M // 2)]
    short = hosid.Record.from_segments(pieces, rec.dt)
    state = prepare_state(short, model, block_seconds=M * rec.dt)
    assert state.layout.B >= 24 and end_blocks(state).all()
    why = Level().skipped(state, model)
    assert why is not None and "segments' ends" in why
    theta = np.array([PAPER[p] for p in model.param_names])
    assert Level().prepare(state, model, theta).k == 0

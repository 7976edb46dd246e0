"""Records of several channels: the Record, its files, and the checks across channels.

Oracles: a record of one displacement channel named ``x`` is today's (same samples,
hash, files); a file written and read back gives the same samples (exactly from
``.npz``, to the 10 digits written from CSV), channels, segments and kinds; the checks
are judged on a simulated linear 2-dof chain (400 s at dt = 0.02, fixed seed) and on
copies of it made dead, duplicated, proportional, held, interpolated or resampled.
"""

import hashlib
import re

import numpy as np
import pytest

from hosid.errors import HosidInputError, RecordRejected
from hosid.model.chain import simulate_chain, write_chain_record
from hosid.model.system import System
from hosid.model.system_file import MEASURED_KINDS
from hosid.record import MEASURED, Record, read_record, write_record
from hosid.record.channel_checks import check_channels
from hosid.screen import check_record, record_statistics, reject_failures

DT = 0.02
#: A linear 2-dof chain: modes 3.9 and 8.1 rad/s.
LINEAR2 = System(
    ("x1", "x2"),
    [(("ground", "x1"), ("linear",)), (("x1", "x2"), ("linear",))],
    values={
        "a1[ground-x1]": 1.0, "a2[ground-x1]": 25.0, "a1[x1-x2]": 0.5, "a2[x1-x2]": 15.0,
        "mass[x2]": 0.5, "S0[x1]": 10.0, "S0[x2]": 5.0,
    },
)  # fmt: skip


def _record(chain: Record, name="chain") -> Record:
    return Record(chain.x, chain.dt, name, channels=chain.channels, measured=chain.measured)


@pytest.fixture(scope="module")
def chain() -> Record:
    return _record(simulate_chain(LINEAR2, duration=400.0, dt=DT, rng=np.random.default_rng(1)))


@pytest.fixture
def two() -> Record:
    rng = np.random.default_rng(3)
    return Record(rng.standard_normal((40, 2)), 0.1, "two", channels=("x1", "x2"))


# ------------------------------------------------------------------------ the Record
def test_single_channel_is_todays_record():
    x = np.random.default_rng(7).standard_normal(200)
    rec = Record(x, 0.02, "r")
    assert rec.channels == ("x",) and rec.measured == ("displacement",)
    assert rec.n_channels == 1 and rec.x.shape == (200,) and rec.samples.shape == (200, 1)
    h = hashlib.sha256(rec.x.tobytes())
    h.update(np.float64(0.02).tobytes())
    assert rec.hash == h.hexdigest()[:16]
    assert Record(x, 0.02, channels=("q",)).hash == rec.hash  # one displacement: any name
    assert Record(x, 0.02, measured="acceleration").hash != rec.hash
    assert repr(rec) == "Record(n=200, dt=0.02, name='r')"
    assert MEASURED == MEASURED_KINDS  # the model's list is the record's


def test_several_channels(two):
    assert two.n == 40 and two.n_channels == 2 and two.x.shape == (40, 2)
    assert not two.x.flags.writeable
    np.testing.assert_array_equal(two.samples, two.x)
    one = two.channel("x2")
    assert one.channels == ("x2",) and one.x.shape == (40,)
    np.testing.assert_array_equal(one.x, two.x[:, 1])
    swapped = two.select(["x2", "x1"])
    np.testing.assert_array_equal(swapped.x, two.x[:, ::-1])
    assert len({two.hash, swapped.hash, one.hash}) == 3
    renamed = Record(two.x, 0.1, channels=("a", "b"))
    assert renamed.hash != two.hash
    assert repr(two) == "Record(n=40, dt=0.1, name='two', channels=('x1', 'x2'))"
    # a single column is stored 1-D
    assert Record(two.x[:, :1], 0.1, channels=["x1"]).x.shape == (40,)


def test_segments_and_kinds_of_several_channels():
    rng = np.random.default_rng(4)
    rec = Record.from_segments(
        [rng.standard_normal((20, 2)), rng.standard_normal((30, 2))],
        0.5,
        "s",
        channels=("u", "w"),
        measured={"w": "acceleration"},
    )
    assert rec.segments == (0, 20) and rec.measured == ("displacement", "acceleration")
    parts = rec.split(rec.samples, axis=0)
    assert [p.shape for p in parts] == [(20, 2), (30, 2)]
    assert [p.shape for p in rec.split(rec.channel("u").x)] == [(20,), (30,)]
    assert rec.channel("w").measured == ("acceleration",)
    assert "measured=('displacement', 'acceleration')" in repr(rec)
    declared = rec.select(["u", "w"], measured={"u": "acceleration"})
    assert declared.measured == ("acceleration", "acceleration")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"x": np.zeros((20, 2))},
         "record samples must be 1-D, got shape (20, 2) (several channels need their names: "
         "channels=...)"),
        ({"x": np.zeros((20, 2)), "channels": ("a", "b", "c")},
         "record samples of 3 channels must be (n_samples, 3), got shape (20, 2)"),
        ({"x": np.zeros((20, 2)), "channels": ("a", "a")}, "channel 'a' given twice"),
        ({"x": np.zeros((20, 2)), "channels": ("a", "t")},
         "bad channel name 't': a non-empty name without commas, quotes or surrounding "
         "spaces, none of t, dt, segment, dofs, measured"),
        ({"x": np.zeros((20, 2)), "channels": ("a", "b,c")},
         "bad channel name 'b,c': a non-empty name without commas, quotes or surrounding "
         "spaces, none of t, dt, segment, dofs, measured"),
        ({"x": np.zeros((20, 2)), "channels": ("a", "b"), "measured": "velocity"},
         "channel 'a': measured must be one of displacement, acceleration, got 'velocity'"),
        ({"x": np.zeros((20, 2)), "channels": ("a", "b"), "measured": ("displacement",)},
         "measured names 1 kinds for 2 channels (a, b)"),
        ({"x": np.zeros((20, 2)), "channels": ("a", "b"), "measured": {"c": "acceleration"}},
         "measured names channel 'c', not one of a, b"),
        ({"x": np.zeros((10, 2)), "channels": ("a", "b")},
         "record has 10 samples; at least 16 are needed"),
    ],
)  # fmt: skip
def test_record_validation_of_channels(kwargs, message):
    with pytest.raises(HosidInputError) as err:
        Record(dt=0.1, **kwargs)
    assert str(err.value) == message


def test_non_finite_sample_names_the_channel():
    x = np.zeros((20, 2))
    x[5, 1] = np.nan
    with pytest.raises(HosidInputError) as err:
        Record(x, 0.1, channels=("a", "b"))
    assert str(err.value) == "record sample 5 of channel 'b' is nan (1 non-finite samples in all)"


@pytest.mark.parametrize(
    ("channels", "measured", "message"),
    [
        (["x1", "x3"], None, "record 'two' has no channel 'x3'; its channels: x1, x2"),
        ([], None, "select needs at least one channel name"),
        (["x2"], "displacement",
         "channel 'x2' of record 'two' is an acceleration (its file says so) but was declared "
         "a displacement"),
    ],
)  # fmt: skip
def test_select_errors(two, channels, measured, message):
    rec = Record(
        two.x, two.dt, "two", channels=two.channels, measured=("displacement", "acceleration")
    )
    with pytest.raises(HosidInputError) as err:
        rec.select(channels, measured=measured)
    assert str(err.value) == message


def test_segments_need_two_dimensional_pieces_with_channels():
    with pytest.raises(HosidInputError) as err:
        Record.from_segments([np.zeros(20)], 0.1, channels=("a",))
    assert str(err.value) == "segments must be a non-empty list of 2-D arrays (samples, channels)"


# ----------------------------------------------------------------------------- files
def _write(path, text):
    path.write_text(text)
    return path


def _csv_rows(n=20, cols=3):
    return "".join(f"{0.1 * i!r}," + ",".join(f"{i * (k + 1)}" for k in range(cols - 1)) + "\n"
                   for i in range(n))  # fmt: skip


def test_csv_of_several_channels(tmp_path):
    rec = read_record(_write(tmp_path / "c.csv", "t,y1,y2\n" + _csv_rows()))
    assert rec.channels == ("y1", "y2") and rec.x.shape == (20, 2) and rec.name == "c"
    np.testing.assert_array_equal(rec.x[:, 1], 2.0 * np.arange(20))
    assert rec.dt == pytest.approx(0.1)
    picked = read_record(tmp_path / "c.csv", channels=["y2", "y1"])
    np.testing.assert_array_equal(picked.x, rec.x[:, ::-1])
    one = read_record(tmp_path / "c.csv", channels="y2")
    assert one.channels == ("y2",) and one.x.shape == (20,)
    # with a column x the file is the single oscillator's, other columns ignored
    single = read_record(_write(tmp_path / "s.csv", "t,x,force\n" + _csv_rows()))
    assert single.channels == ("x",) and single.x.shape == (20,)


@pytest.mark.parametrize(
    ("header", "channels", "message"),
    [
        ("t,y1,y2", ["y1", "z"], "{p}: no column 'z' (asked for y1, z; the file has t, y1, y2)"),
        ("t,y1,y1", None, "{p}: channel 'y1' given twice"),
        ("t,y1", None,
         "{p}: no column 'x' in header 't,y1' (one channel is the column x; a system file's "
         "dofs name other columns)"),
    ],
)  # fmt: skip
def test_csv_channel_errors(tmp_path, header, channels, message):
    path = _write(tmp_path / "e.csv", header + "\n" + _csv_rows(cols=header.count(",") + 1))
    with pytest.raises(HosidInputError) as err:
        read_record(path, channels=channels)
    assert str(err.value) == message.format(p=path)


def test_csv_segments_of_several_channels(tmp_path):
    t = np.r_[np.arange(20) * 0.1, 50 + np.arange(20) * 0.1]
    rows = [f"{float(ti)!r},{i},{-i},{int(i >= 20)}" for i, ti in enumerate(t)]
    rec = read_record(_write(tmp_path / "g.csv", "t,a,b,segment\n" + "\n".join(rows)))
    assert rec.segments == (0, 20) and rec.channels == ("a", "b")


def test_npz_with_a_2d_array_and_dofs(tmp_path):
    q = np.random.default_rng(5).standard_normal((32, 3))
    np.savez(tmp_path / "q.npz", q=q, dofs=np.array(["a", "b", "c"]), dt=0.5,
             measured=np.array(["displacement", "acceleration", "displacement"]))  # fmt: skip
    rec = read_record(tmp_path / "q.npz")
    np.testing.assert_array_equal(rec.x, q)
    assert rec.channels == ("a", "b", "c") and rec.dt == 0.5
    assert rec.measured == ("displacement", "acceleration", "displacement")
    np.savez(tmp_path / "t.npz", q=q, dofs=np.array(["a", "b", "c"]), t=0.25 * np.arange(32),
             measured="acceleration", segment=np.repeat([0, 1], 16))  # fmt: skip
    rec = read_record(tmp_path / "t.npz", channels=["c", "a"])
    assert rec.channels == ("c", "a") and rec.segments == (0, 16) and rec.dt == 0.25
    assert rec.measured == ("acceleration", "acceleration")


@pytest.mark.parametrize(
    ("arrays", "message"),
    [
        ({"q": np.zeros((20, 2)), "dt": 0.1},
         "{p}: a 2-D 'q' needs 'dofs', the names of its columns (one a channel)"),
        ({"q": np.zeros((20, 3)), "dofs": np.array(["a", "b"]), "dt": 0.1},
         "{p}: 'q' must be (n_samples, 2), one column a name of dofs (a, b); got shape (20, 3)"),
        ({"a": np.zeros(20), "dofs": np.array(["a", "b"]), "dt": 0.1},
         "{p}: no array 'b' (asked for a, b; the file has a, dofs, dt)"),
        ({"a": np.zeros(20), "b": np.zeros(19), "dofs": np.array(["a", "b"]), "dt": 0.1},
         "{p}: the channels a, b must be 1-D arrays of one length, got shapes (20,), (19,)"),
        ({"q": np.zeros((20, 2)), "dofs": np.array([1, 2]), "dt": 0.1},
         "{p}: 'dofs' must be a 1-D array of channel names"),
        ({"q": np.zeros((20, 2)), "dofs": np.array(["a", "b"])},
         "{p}: needs an array 't' or 'dt' besides the channels"),
        ({"q": np.zeros((20, 2)), "dofs": np.array(["a", "b"]), "dt": 0.1,
          "measured": np.array(["velocity", "displacement"])},
         "{p}: channel 'a': measured must be one of displacement, acceleration, got 'velocity'"),
        ({"q": np.zeros((20, 2)), "dofs": np.array(["a", "b"]), "dt": 0.1},
         "{p}: no channel 'z' (asked for z; the file has a, b)"),
    ],
)  # fmt: skip
def test_npz_channel_errors(tmp_path, arrays, message):
    path = tmp_path / "e.npz"
    np.savez(path, **arrays)
    with pytest.raises(HosidInputError) as err:
        read_record(path, channels=["z"] if message.endswith("the file has a, b)") else None)
    assert str(err.value) == message.format(p=path)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip_of_several_channels(tmp_path, suffix):
    rng = np.random.default_rng(6)
    rec = Record.from_segments(
        [rng.standard_normal((30, 2)), rng.standard_normal((20, 2))],
        0.05,
        "m",
        channels=("x1", "x2"),
        measured=("displacement", "acceleration"),
    )
    back = read_record(write_record(rec, tmp_path / f"m{suffix}"))
    assert back.channels == rec.channels and back.segments == rec.segments
    assert back.dt == pytest.approx(rec.dt, rel=1e-12)
    if suffix == ".npz":  # exact, with what each channel measures
        np.testing.assert_array_equal(back.x, rec.x)
        assert back.measured == rec.measured and back.hash == rec.hash
    else:  # 10 digits; a CSV does not say what a channel measures
        assert (tmp_path / "m.csv").read_text().splitlines()[0] == "t,x1,x2,segment"
        np.testing.assert_allclose(back.x, rec.x, rtol=1e-9)
        assert back.measured == ("displacement", "displacement")
        assert back.select(back.channels, measured=rec.measured).measured == rec.measured


def test_one_channel_not_named_x_round_trips(tmp_path):
    rec = Record(np.arange(20.0), 0.1, channels=("x2",), measured="acceleration")
    back = read_record(write_record(rec, tmp_path / "o.npz"))
    assert back.channels == ("x2",) and back.measured == ("acceleration",)
    back = read_record(write_record(rec, tmp_path / "o.csv"), channels=["x2"])
    np.testing.assert_array_equal(back.x, rec.x)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_chain_records_read_as_records(tmp_path, suffix):
    run = simulate_chain(LINEAR2, duration=10.0, dt=DT, rng=np.random.default_rng(7),
                         measured={"x2": "acceleration"})  # fmt: skip
    back = read_record(write_chain_record(run, tmp_path / f"c{suffix}"))
    assert back.channels == ("x1", "x2")
    np.testing.assert_allclose(back.x, run.x, rtol=1e-9)
    if suffix == ".npz":
        assert back.measured == ("displacement", "acceleration")
        assert back.hash == _record(run, "c").hash


# ---------------------------------------------------------------------------- checks
def _statuses(checks):
    return {c.name: c.status for c in checks}


def test_a_good_chain_passes(chain):
    checks = check_record(chain)
    assert [c.name for c in checks] == [
        "dead", "duplicate", "resampled", "length", "sampling", "offset", "trend", "clipping",
        "quantisation", "oscillator",
    ]  # fmt: skip
    assert set(_statuses(checks).values()) == {"pass"}
    assert checks[-1].message.endswith("(channels: x1 pass, x2 pass)")
    assert checks == check_channels(chain)


def test_single_displacement_channel_checks_unchanged(chain):
    one = chain.channel("x1")
    plain = Record(one.x, one.dt, one.name)
    assert check_record(one) == check_record(plain)
    assert check_record(plain)[0].name == "length"


def test_acceleration_channels_are_integrated_first():
    run = simulate_chain(LINEAR2, duration=400.0, dt=DT, rng=np.random.default_rng(1),
                         measured="acceleration")  # fmt: skip
    checks = check_record(_record(run))
    assert set(_statuses(checks).values()) == {"pass"}
    assert "integration" in _statuses(checks) and "offset" not in _statuses(checks)
    band = next(c for c in checks if c.name == "integration")
    assert band.message.startswith("channel x1: integrated above ")
    clip = next(c for c in checks if c.name == "clipping")
    assert " m/s^2 " in clip.message
    # one acceleration channel: the same checks, without the channel's name
    alone = check_record(_record(run).channel("x2"))
    assert [c.name for c in alone] == [
        "length", "sampling", "integration", "clipping", "quantisation", "oscillator"
    ]  # fmt: skip
    assert alone[2].message.startswith("integrated above ")


def _pair(chain, second):
    return Record(np.column_stack([chain.x[:, 0], second]), DT, "bad", channels=("x1", "x2"))


def _resample_fft(y, factor):
    """``y`` low-passed below ``1/factor`` of the Nyquist frequency (a channel decimated
    and interpolated back to the record's rate).
    """
    F = np.fft.rfft(y)
    F[F.size // factor :] = 0.0
    return np.fft.irfft(F, y.size)


@pytest.mark.parametrize(
    ("make", "name", "message"),
    [
        (lambda x: np.zeros_like(x), "dead",
         "channel x2 is dead: all zeros over its 20000 samples: a disconnected or broken "
         "sensor?"),
        (lambda x: np.full_like(x, 2.5), "dead",
         "channel x2 is dead: constant at 2.5 over its 20000 samples: a disconnected or "
         "broken sensor?"),
        (lambda x: x, "duplicate",
         "channels x1 and x2 are identical (correlation 1): one sensor recorded twice, or a "
         "rigid link whose law cannot be identified"),
        (lambda x: 1.0 - 2.0 * x, "duplicate",
         "channels x1 and x2 are proportional: x2 = -2 x1 (+ a constant) (correlation -1): "
         "one sensor recorded twice, or a rigid link whose law cannot be identified"),
        (lambda x: np.repeat(x[::4], 4), "resampled",
         "channel x2: 75 % of its first differences vanish: held between samples taken "
         "every 4 samples (0.08 s), not every 0.02 s"),
        (lambda x: np.interp(np.arange(x.size), np.arange(0, x.size, 5), x[::5]), "resampled",
         "channel x2: 80 % of its second differences vanish: interpolated linearly between "
         "samples taken every 5 samples (0.1 s), not every 0.02 s"),
    ],
)  # fmt: skip
def test_bad_channels_get_a_verdict(chain, make, name, message):
    second = chain.x[:, 1] if name in ("dead", "resampled") else chain.x[:, 0]
    checks = check_record(_pair(chain, make(second)))
    failed = [c for c in checks if c.status == "fail"]
    assert [c.name for c in failed] == [name]
    assert failed[0].message == message
    with pytest.raises(RecordRejected, match=f"^{name}: "):
        reject_failures(checks)


def test_a_channel_band_limited_alone_is_resampled(chain):
    checks = check_record(_pair(chain, _resample_fft(chain.x[:, 1], 4)))
    bad = next(c for c in checks if c.name == "resampled")
    assert bad.status == "fail"
    found = re.fullmatch(
        r"channel x2: its spectrum falls (\S+)-fold at (\S+) rad/s and stays down to the "
        r"Nyquist frequency 157.1 rad/s, where the other channels do not: sampled at a lower "
        r"rate and interpolated\?",
        bad.message,
    )
    assert found and float(found[1]) > 1e6
    # the cut at a quarter of the Nyquist frequency, to the Welch spectrum's main lobe
    # (nperseg 1024: 0.31 rad/s a bin, the Hann lobe 2 bins wide)
    assert float(found[2]) == pytest.approx(np.pi / DT / 4, abs=3 * 0.307)


def test_a_band_limit_common_to_all_channels_is_not_a_resampling(chain):
    both = np.column_stack([_resample_fft(chain.x[:, k], 4) for k in range(2)])
    checks = check_record(Record(both, DT, "edge", channels=chain.channels))
    assert _statuses(checks)["resampled"] == "pass"


def test_a_quantised_channel_is_not_held(chain):
    step = chain.x[:, 1].std() / 10.0
    checks = check_record(_pair(chain, np.round(chain.x[:, 1] / step) * step))
    assert _statuses(checks)["resampled"] == "pass"
    assert _statuses(checks)["quantisation"] == "warn"


def test_short_record_names_the_channel(chain):
    short = Record(chain.x[:2000], DT, "short", channels=chain.channels)
    with pytest.raises(HosidInputError, match=r"^channel x1: record of 40 s is too short"):
        check_record(short)


def test_record_statistics_take_one_channel(chain):
    with pytest.raises(HosidInputError) as err:
        record_statistics(chain)
    assert str(err.value) == "record_statistics takes one channel: use record.channel(name)"
    assert record_statistics(chain.channel("x2"))["n"] == chain.n

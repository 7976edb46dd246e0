"""Reading, writing and validating records; the record hash that guards a chain."""

import numpy as np
import pytest

from hosid.errors import HosidInputError
from hosid.record import MIN_SAMPLES, Record, read_record, write_record


@pytest.fixture
def record() -> Record:
    rng = np.random.default_rng(7)
    return Record(rng.standard_normal(200), 0.02, name="r")


def test_record_properties(record):
    assert record.n == 200
    assert record.duration == pytest.approx(4.0)
    np.testing.assert_allclose(record.t, 0.02 * np.arange(200))
    assert record.x.dtype == np.float64
    assert not record.x.flags.writeable
    assert repr(record) == "Record(n=200, dt=0.02, name='r')"


def test_record_copies_and_converts():
    x = np.arange(16)
    rec = Record(x, 1)
    assert rec.x.dtype == np.float64
    assert isinstance(rec.dt, float)
    x[0] = 99  # the record holds its own copy
    assert rec.x[0] == 0.0
    assert MIN_SAMPLES == 16


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_round_trip(record, tmp_path, suffix):
    path = write_record(record, tmp_path / f"rec{suffix}")
    assert path == tmp_path / f"rec{suffix}"
    back = read_record(path)
    assert back.n == record.n
    assert back.name == "rec"
    if suffix == ".npz":  # exact
        np.testing.assert_array_equal(back.x, record.x)
        assert back.dt == record.dt
        assert back.hash == record.hash
    else:  # 10 significant digits for x, 15 for t
        np.testing.assert_allclose(back.x, record.x, rtol=1e-9, atol=0)
        assert back.dt == pytest.approx(record.dt, rel=1e-12)


def test_csv_round_trip_long_record_stays_uniform(tmp_path):
    # 100 000 samples at an awkward dt: the written times must read back uniform
    rec = Record(np.zeros(100_000), 0.0123456789123)
    back = read_record(write_record(rec, tmp_path / "long.csv"))
    assert back.dt == pytest.approx(rec.dt, rel=1e-12)


def test_hash_is_stable_and_sensitive(record):
    again = Record(record.x.copy(), record.dt, name="another name")
    assert again.hash == record.hash  # samples and dt only, not the name
    assert len(record.hash) == 16
    int(record.hash, 16)
    x = record.x.copy()
    x[123] = np.nextafter(x[123], np.inf)  # one sample, one ulp
    assert Record(x, record.dt).hash != record.hash
    assert Record(record.x, 0.02000001).hash != record.hash


def test_csv_column_order_and_extra_columns(tmp_path):
    t = 0.5 * np.arange(20)
    x = np.sin(t)
    path = tmp_path / "cols.csv"
    rows = "\n".join(f"{float(xi)!r},7,{float(ti)!r}" for ti, xi in zip(t, x, strict=True))
    path.write_text(f'x, force ,"t"\n{rows}\n')
    rec = read_record(path)
    assert rec.dt == pytest.approx(0.5)
    np.testing.assert_allclose(rec.x, x)


def test_npz_with_times_or_dt(tmp_path):
    t = 0.1 * np.arange(32)
    np.savez(tmp_path / "a.npz", t=t, x=np.cos(t))
    rec = read_record(tmp_path / "a.npz")
    assert rec.dt == pytest.approx(0.1)
    assert rec.n == 32
    np.savez(tmp_path / "b.npz", dt=0.25, x=np.cos(t))
    assert read_record(tmp_path / "b.npz").dt == 0.25


def _csv(tmp_path, t, x, name="bad.csv"):
    path = tmp_path / name
    lines = ["t,x", *(f"{float(ti)!r},{float(xi)!r}" for ti, xi in zip(t, x, strict=True))]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_sample_names_index(tmp_path, bad):
    x = np.ones(20)
    x[5] = bad
    path = _csv(tmp_path, np.arange(20.0), x)
    with pytest.raises(HosidInputError, match="sample 5 is"):
        read_record(path)
    with pytest.raises(HosidInputError, match="sample 5 is"):
        Record(x, 1.0)


def test_non_uniform_sampling(tmp_path):
    t = np.arange(20.0)
    t[10] += 1e-3
    with pytest.raises(HosidInputError, match=r"non-uniform sampling.*step 9"):
        read_record(_csv(tmp_path, t, np.zeros(20)))
    np.savez(tmp_path / "b.npz", t=t, x=np.zeros(20))
    with pytest.raises(HosidInputError, match="non-uniform sampling"):
        read_record(tmp_path / "b.npz")


def test_decreasing_or_bad_times(tmp_path):
    with pytest.raises(HosidInputError, match="times must increase"):
        read_record(_csv(tmp_path, -np.arange(20.0), np.zeros(20)))
    t = np.arange(20.0)
    t[3] = np.nan
    np.savez(tmp_path / "c.npz", t=t, x=np.zeros(20))
    with pytest.raises(HosidInputError, match="time 3 is nan"):
        read_record(tmp_path / "c.npz")
    np.savez(tmp_path / "d.npz", t=np.arange(20.0), x=np.zeros(19))
    with pytest.raises(HosidInputError, match="t has shape"):
        read_record(tmp_path / "d.npz")


@pytest.mark.parametrize("col", ["t", "x"])
def test_missing_column(tmp_path, col):
    other = "x" if col == "t" else "t"
    path = tmp_path / "c.csv"
    path.write_text(f"{other},y\n" + "".join(f"{i},{i}\n" for i in range(20)))
    with pytest.raises(HosidInputError, match=f"no column '{col}'"):
        read_record(path)


def test_npz_missing_or_bad_arrays(tmp_path):
    np.savez(tmp_path / "d.npz", x=np.zeros(20))
    with pytest.raises(HosidInputError, match="'t' or 'dt'"):
        read_record(tmp_path / "d.npz")
    np.savez(tmp_path / "e.npz", dt=0.1)
    with pytest.raises(HosidInputError, match="no array 'x'"):
        read_record(tmp_path / "e.npz")
    np.savez(tmp_path / "f.npz", dt=np.array([0.1, 0.2]), x=np.zeros(20))
    with pytest.raises(HosidInputError, match="dt must be a single number"):
        read_record(tmp_path / "f.npz")


def test_missing_file(tmp_path):
    with pytest.raises(HosidInputError, match="no such file"):
        read_record(tmp_path / "nope.csv")


@pytest.mark.parametrize("name", ["rec.txt", "rec"])
def test_unknown_suffix(record, tmp_path, name):
    (tmp_path / name).write_text("t,x\n")
    with pytest.raises(HosidInputError, match="unknown file type"):
        read_record(tmp_path / name)
    with pytest.raises(HosidInputError, match="unknown file type"):
        write_record(record, tmp_path / name)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("", "empty file"),
        ("t,x\n", "no data rows"),
        ("t,x\n\n  \n", "no data rows"),
        ("t,x\n0,1\n1,oops\n", "bad.csv"),
    ],
)
def test_empty_or_unreadable_csv(tmp_path, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(HosidInputError, match=match):
        read_record(path)


def test_short_csv_is_rejected(tmp_path):
    with pytest.raises(HosidInputError, match="at least 16 are needed"):
        read_record(_csv(tmp_path, np.arange(10.0), np.zeros(10)))


def test_corrupt_npz(tmp_path):
    path = tmp_path / "bad.npz"
    path.write_bytes(b"not a zip file")
    with pytest.raises(HosidInputError, match="cannot read"):
        read_record(path)


def test_write_to_missing_directory(record, tmp_path):
    with pytest.raises(HosidInputError, match="cannot write"):
        write_record(record, tmp_path / "no" / "such" / "dir.csv")


@pytest.mark.parametrize(
    ("x", "dt", "match"),
    [
        (np.zeros(15), 1.0, "at least 16"),
        (np.zeros((4, 8)), 1.0, "1-D"),
        (np.zeros(20, dtype=complex), 1.0, "real numbers"),
        (np.array(["a"] * 20), 1.0, "real numbers"),
        (np.zeros(20), 0.0, "dt must be finite and positive"),
        (np.zeros(20), -0.1, "dt must be finite and positive"),
        (np.zeros(20), np.nan, "dt must be finite and positive"),
        (np.zeros(20), np.inf, "dt must be finite and positive"),
        (np.zeros(20), "fast", "dt must be a number"),
    ],
)
def test_record_validation(x, dt, match):
    with pytest.raises(HosidInputError, match=match) as err:
        Record(x, dt)
    assert "\n" not in str(err.value)


def test_input_error_is_value_error():
    assert issubclass(HosidInputError, ValueError)


# ------------------------------------------------------------------------ segments
@pytest.fixture
def segmented() -> Record:
    rng = np.random.default_rng(8)
    return Record.from_segments([rng.standard_normal(n) for n in (40, 16, 25)], 0.5, "seg")


def test_segments_layout(segmented):
    assert segmented.segments == (0, 40, 56)
    assert segmented.bounds == ((0, 40), (40, 56), (56, 81))
    assert segmented.n_segments == 3 and segmented.n == 81
    parts = segmented.split(segmented.x)
    assert [p.size for p in parts] == [40, 16, 25]
    np.testing.assert_array_equal(np.concatenate(parts), segmented.x)
    np.testing.assert_array_equal(np.bincount(segmented.labels), [40, 16, 25])
    assert repr(segmented) == "Record(n=81, dt=0.5, name='seg', segments=3)"


def test_one_segment_is_the_default_and_hashes_as_before(record):
    import hashlib

    assert record.segments == (0,) and record.n_segments == 1
    h = hashlib.sha256(record.x.tobytes())
    h.update(np.float64(record.dt).tobytes())
    assert record.hash == h.hexdigest()[:16]
    assert Record(record.x, record.dt, segments=[0]).hash == record.hash


def test_hash_covers_the_segments(segmented):
    joined = Record(segmented.x, segmented.dt)
    moved = Record(segmented.x, segmented.dt, segments=(0, 41, 57))
    assert len({segmented.hash, joined.hash, moved.hash}) == 3


@pytest.mark.parametrize(
    ("segments", "match"),
    [
        ((5, 30), "first segment must start at sample 0"),
        ((0, 10), "segment 0 .* has 10 samples"),
        ((0, 50, 40), "segment 1 .* has -10 samples"),
        ((0, 70), "segment 1 .* has 11 samples"),
        ((0.0, 40.0), "start indices"),
        ([], "start indices"),
    ],
)
def test_bad_segment_starts(segments, match):
    with pytest.raises(HosidInputError, match=match):
        Record(np.zeros(81), 0.1, segments=segments)


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_segmented_round_trip(segmented, tmp_path, suffix):
    back = read_record(write_record(segmented, tmp_path / f"s{suffix}"))
    assert back.segments == segmented.segments
    assert back.dt == pytest.approx(segmented.dt, rel=1e-12)
    np.testing.assert_allclose(back.x, segmented.x, rtol=1e-9, atol=0)
    if suffix == ".npz":
        assert back.hash == segmented.hash


def _seg_csv(tmp_path, t, x, seg, name="s.csv"):
    path = tmp_path / name
    rows = [f"{ti!r},{xi!r},{si}" for ti, xi, si in zip(t, x, seg, strict=True)]
    path.write_text("t,x,segment\n" + "\n".join(rows))
    return path


def test_csv_segments_may_jump_in_time(tmp_path):
    t = np.r_[np.arange(20) * 0.1, 100.0 + np.arange(30) * 0.1, -5 + np.arange(16) * 0.1]
    seg = np.r_[np.full(20, 7), np.full(30, 2), np.full(16, 9)]
    rec = read_record(_seg_csv(tmp_path, t.tolist(), np.arange(66.0).tolist(), seg.tolist()))
    assert rec.segments == (0, 20, 50)
    assert rec.dt == pytest.approx(0.1, rel=1e-9)


@pytest.mark.parametrize(
    ("seg", "t_bump", "match"),
    [
        ([0] * 20 + [1.5] * 20, None, r"line 22, column 'segment': 1.5 is not an integer"),
        ([0] * 20 + [1] * 10 + [0] * 10, None, "segment 0 is not contiguous: .* line 32"),
        ([0] * 20 + [1] * 20, 25, r"non-uniform sampling in segment 1: .*step 5"),
        ([0] * 20 + [1] * 20, 0, r"non-uniform sampling in segment 0: .*step 0"),
    ],
)
def test_csv_bad_segments(tmp_path, seg, t_bump, match):
    t = np.r_[np.arange(20) * 0.1, 50 + np.arange(20) * 0.1]
    if t_bump is not None:
        t[t_bump + 1] += 0.03
    with pytest.raises(HosidInputError, match=match) as err:
        read_record(_seg_csv(tmp_path, t.tolist(), np.zeros(40).tolist(), seg))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("row", "match"),
    [
        ("0.3,abc", r"line 5, column 'x': 'abc' is not a number"),
        ("zz,1", r"line 5, column 't': 'zz' is not a number"),
        ("0.3", r"line 5 has 1 fields; column 'x' is field 2"),
    ],
)
def test_csv_bad_cell_names_column_and_line(tmp_path, row, match):
    lines = ["t,x", *(f"{0.1 * i!r},1" for i in range(3)), row]
    lines += [f"{0.1 * i!r},1" for i in range(4, 20)]
    path = tmp_path / "cells.csv"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(HosidInputError, match=match):
        read_record(path)


def test_npz_segments_as_rows_or_labels(tmp_path):
    x = np.arange(60.0).reshape(3, 20)
    np.savez(tmp_path / "rows.npz", x=x, dt=0.2)
    rec = read_record(tmp_path / "rows.npz")
    assert rec.segments == (0, 20, 40)
    np.testing.assert_array_equal(rec.x, x.ravel())
    t = 0.2 * np.arange(20) + np.array([[0.0], [10.0], [30.0]])
    np.savez(tmp_path / "rows_t.npz", x=x, t=t)
    assert read_record(tmp_path / "rows_t.npz").dt == pytest.approx(0.2)
    np.savez(tmp_path / "lab.npz", x=x.ravel(), dt=0.2, segment=np.repeat([4, 1, 2], 20))
    assert read_record(tmp_path / "lab.npz").segments == (0, 20, 40)
    np.savez(tmp_path / "bad.npz", x=x.ravel(), dt=0.2, segment=np.zeros(5))
    with pytest.raises(HosidInputError, match="one integer label a sample"):
        read_record(tmp_path / "bad.npz")


def test_directory_and_non_archive(tmp_path):
    (tmp_path / "d.csv").mkdir()
    with pytest.raises(HosidInputError, match="is a folder"):
        read_record(tmp_path / "d.csv")
    (tmp_path / "adir").mkdir()  # no suffix: named a folder, not an unknown type
    with pytest.raises(HosidInputError, match="adir: is a folder"):
        read_record(tmp_path / "adir")
    (tmp_path / "p.npz").write_bytes(b"\x80\x04not a zip at all")
    with pytest.raises(HosidInputError, match=r"not an \.npz archive") as err:
        read_record(tmp_path / "p.npz")
    assert "pickle" not in str(err.value)


def test_a_pickled_record_is_an_aligned_copy_with_its_segments():
    import pickle

    rec = Record.from_segments([np.arange(20.0), np.arange(30.0)], 0.1, "r")
    blob = bytearray(b"\x00" + pickle.dumps(rec))  # misaligned in its buffer
    back = pickle.loads(memoryview(blob)[1:])
    assert back.segments == rec.segments and back.hash == rec.hash and back.name == "r"
    assert back.x.flags.aligned and not back.x.flags.writeable
    np.testing.assert_array_equal(back.x, rec.x)

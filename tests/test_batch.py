"""hosid batch: seeds, designs, the results table, resume, the lock, dead workers.

Runs on short records (300 s) with fixed emcee steps or ``estimate``, on one shared
local cluster of two worker processes (and one of one worker for the comparison).
"""

import csv
import json
import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

import hosid
from hosid.batch import (
    design_tasks,
    expand_inputs,
    read_design,
    read_results,
    record_tasks,
    run_batch,
    run_task,
)
from hosid.batch.runner import local_cluster
from hosid.batch.table import TIMES
from hosid.cli import main
from hosid.errors import HosidInputError, RecordRejected
from hosid.output.files import locked_dir
from hosid.output.results import load, versions
from hosid.record import write_record
from hosid.verdicts import Check

FIT = {"n_steps": 150, "n_walkers": 12}


@pytest.fixture(scope="module")
def records(tmp_path_factory):
    """Four short paper-oscillator records with their truths, and a corrupt one."""
    folder = tmp_path_factory.mktemp("records")
    for i in range(4):
        rec = hosid.simulate(
            hosid.PAPER_PARAMS, duration=300.0, dt=0.02, rng=np.random.default_rng(i), name=f"r{i}"
        )
        write_record(rec, folder / f"r{i}.npz")
        (folder / f"r{i}.truths.json").write_text(json.dumps(hosid.PAPER_PARAMS))
    (folder / "r9_corrupt.csv").write_text("t,x\n0,1\n0.02,oops\n")
    return folder


@pytest.fixture(scope="module")
def cluster():
    """Two worker processes, one thread each (as ``--workers 2``)."""
    c = local_cluster(2)
    yield c.scheduler_address
    c.close()


def _table(path: Path) -> list[dict]:
    """results.csv without the timing columns, rows in input order."""
    with path.open() as fh:
        return [{k: v for k, v in r.items() if k not in TIMES} for r in csv.DictReader(fh)]


def _design(folder: Path, text: str, suffix: str = ".csv"):
    path = folder / f"design{suffix}"
    path.write_text(text)
    return read_design(path)


def test_seeds_are_spawn_positions_and_ids_are_stable(records, tmp_path):
    path = str(records / "r0.npz")
    t = record_tasks([path], analysis="fit", options={})[0].prepare()
    h = int(t.record.hash, 16)
    assert t.spawn_key == (h,)
    a = t.seed_sequence().generate_state(4)
    np.testing.assert_array_equal(a, np.random.SeedSequence(0, spawn_key=(h,)).generate_state(4))
    # a design point (key r, seed i) is SeedSequence(seed).spawn(r + 1)[r].spawn(i + 1)[i]
    rows = _design(
        tmp_path, "name,key,seeds,a1,n1,a2,n2,S0,duration\nA,3,2,0.5,0.5,25,5,100,200\n"
    )
    p = design_tasks(rows, analysis="estimate", options={}, seed=7)[1]
    ref = np.random.SeedSequence(7).spawn(4)[3].spawn(2)[1]
    np.testing.assert_array_equal(p.seed_sequence().generate_state(4), ref.generate_state(4))
    # the id: defaults given or left out, the same; another option or seed, another id
    same = record_tasks([path], analysis="fit", options={"model": "paper", "n_walkers": 32})
    assert same[0].prepare().id == t.id
    for options, seed in (({"cost": "J4A"}, 0), ({}, 1)):
        other = record_tasks([path], analysis="fit", options=options, seed=seed)[0].prepare()
        assert other.id != t.id
    with pytest.raises(HosidInputError, match="do not apply to fit"):
        record_tasks([path], analysis="fit", options={"replicates": 4})


def test_design_tables_csv_and_json_and_their_errors(tmp_path):
    csv_rows = _design(
        tmp_path,
        "name,a1,n1,a2,n2,S0,duration,seeds\nlow,0.5,0.5,25,5,25,500,3\nhigh,0.5,0.5,25,5,400,,2\n",
    )
    json_rows = _design(
        tmp_path,
        json.dumps(
            [
                {
                    "name": "low",
                    "a1": 0.5,
                    "n1": 0.5,
                    "a2": 25,
                    "n2": 5,
                    "S0": 25,
                    "duration": 500,
                    "seeds": 3,
                },
                {"name": "high", "a1": 0.5, "n1": 0.5, "a2": 25, "n2": 5, "S0": 400, "seeds": 2},
            ]
        ),
        ".json",
    )
    assert csv_rows == json_rows
    assert [(r.name, r.key, r.seeds, r.duration) for r in csv_rows] == [
        ("low", 0, 3, 500.0),
        ("high", 1, 2, 2000.0),
    ]
    tasks = design_tasks(csv_rows, analysis="fit", options={})
    assert [t.label for t in tasks] == ["low-0", "low-1", "low-2", "high-0", "high-1"]
    assert tasks[0].truths == {"a1": 0.5, "n1": 0.5, "a2": 25.0, "n2": 5.0, "S0": 25.0}
    for text, message in (
        ("name,a1,a2,S0,foo\nx,1,25,10,3\n", "unknown column"),
        ("name,key,a1,a2,S0\nx,1,1,25,10\ny,1,1,25,10\n", "share the key"),
        ("name,a1,a2,S0\nx,1,25,-1\n", "S0 must be positive"),
        ("name,a1,a2,S0,seeds\nx,1,25,10,0\n", "seeds"),
        ("name,a1,a2,S0,simulator\nx,1,25,10,nofile.py:sim\n", "no such file"),
    ):
        with pytest.raises(HosidInputError, match=message):
            _design(tmp_path, text)
    with pytest.raises(HosidInputError, match="no file matches"):
        expand_inputs([str(tmp_path / "none*.csv")])


def test_run_task_is_a_pure_function_and_maps_rejection(records, monkeypatch):
    task = record_tasks([str(records / "r0.npz")], analysis="estimate", options={})[0]
    task = task.prepare()
    a = run_task(task, task.seed_sequence()).row
    b = run_task(task, task.seed_sequence()).row
    for row in (a, b):
        for k in TIMES:
            row.pop(k)
    assert a == b and a["status"] == "ok" and a["verdict"] == "pass"
    # estimate: mode +- the Gaussian quantiles of its sd
    assert a["a2_q95"] - a["a2_mean"] == pytest.approx(1.6448536 * a["a2_sd"], rel=1e-6)
    assert a["true_a2"] == 25.0

    checks = [Check("oscillator", "fail", 0.0, "white noise, not an oscillator")]

    def reject(*args, **kwargs):
        raise RecordRejected("not an oscillator", checks)

    monkeypatch.setattr(hosid.inference, "estimate", reject)
    row = run_task(task, task.seed_sequence()).row
    assert (row["status"], row["verdict"]) == ("rejected", "fail")
    assert "oscillator fail" in row["checks"]


def test_one_and_two_workers_give_identical_tables(records, cluster, tmp_path):
    paths = expand_inputs([str(records / "r*.npz")])
    tasks = record_tasks(paths, analysis="fit", options=FIT, seed=3)
    one = run_batch(tasks, tmp_path / "one", workers=1, progress=False, save_posterior=True)
    two = run_batch(
        tasks, tmp_path / "two", scheduler=cluster, progress=False, save_posterior=True
    )
    assert one.counts["ok"] == two.counts["ok"] == 4
    a, b = _table(tmp_path / "one" / "results.csv"), _table(tmp_path / "two" / "results.csv")
    assert a == b  # every digit of every column but the times
    assert [r["record"] for r in a] == paths
    assert all(math.isfinite(float(r["a1_r_hat"])) for r in a)
    # the same fit in this process, and each posterior.nc holds the row's draws
    task = tasks[2].prepare()
    here = run_task(task, task.seed_sequence()).row
    assert repr(here["a1_mean"]) == a[2]["a1_mean"] and repr(here["S0_q95"]) == a[2]["S0_q95"]
    tree = load(tmp_path / "two" / a[2]["posterior"])
    assert float(tree["posterior"]["a1"].mean()) == pytest.approx(here["a1_mean"], rel=1e-12)
    assert "likelihood_map" in tree.children  # kept for hosid report


def test_corrupt_record_error_row_resume_and_lock(records, cluster, tmp_path):
    out = tmp_path / "batch"
    manifest = tmp_path / "records.txt"
    manifest.write_text(f"# the batch\n{records}/r*.npz\n{records}/r9_corrupt.csv\n")
    argv = ["batch", "estimate", str(manifest), "--out", str(out), "--scheduler", cluster]
    assert main([*argv, "--no-progress"]) == 0
    rows = read_results(out / "results.csv")
    assert [Path(r["record"]).name for r in rows] == [f"r{i}.npz" for i in range(4)] + [
        "r9_corrupt.csv"
    ]
    assert [r["status"] for r in rows] == ["ok"] * 4 + ["error"]
    assert "oops" in rows[-1]["message"]
    assert all(r["verdict"] == "pass" and math.isfinite(r["a1_mean"]) for r in rows[:4])
    # the versions the tasks ran with, as summary.json has them; none for a record never read
    ran = {f"version_{k}": v for k, v in versions().items()}
    assert all({k: r[k] for k in ran} == ran for r in rows[:4])
    assert all(rows[-1][k] is None for k in ran)
    assert list(rows[0])[-len(ran) :] == list(ran)

    # rerun: nothing runs again; one row file removed: only that task runs
    tasks = record_tasks(expand_inputs([str(manifest)]), analysis="estimate", options={})
    res = run_batch(tasks, out, scheduler=cluster, progress=False)
    assert (res.skipped, res.ran) == (4, 0) and res.counts["error"] == 1
    victim = next((out / "tasks").glob("*.json"))
    victim.unlink()
    res = run_batch(tasks, out, scheduler=cluster, progress=False)
    assert (res.skipped, res.ran) == (3, 1) and victim.is_file()
    assert len(list((out / "tasks").glob("*.json"))) == 4

    # the lock: a second batch on the folder stops at once
    with locked_dir(out, command="another batch"):
        with pytest.raises(HosidInputError, match="in use"):
            run_batch(tasks, out, scheduler=cluster, progress=False)


def test_worker_that_dies_is_replaced_and_its_task_retried(cluster, tmp_path):
    marker = tmp_path / "died-once"
    sim = tmp_path / "dying_sim.py"
    sim.write_text(
        textwrap.dedent(
            f"""
            import os
            from hosid.model import simulate as hosid_simulate

            def simulate(params, *, duration, dt, rng, name):
                if name.endswith("-1") and not os.path.exists({str(marker)!r}):
                    open({str(marker)!r}, "w").close()
                    os._exit(1)  # the worker process dies in the middle of the task
                return hosid_simulate(params, duration=duration, dt=dt, rng=rng, name=name)
            """
        )
    )
    design = tmp_path / "design.csv"
    design.write_text(
        "name,a1,n1,a2,n2,S0,duration,seeds,simulator\n"
        "p,0.5,0.5,25,5,100,300,3,dying_sim.py:simulate\n"
    )
    tasks = design_tasks(read_design(design), analysis="estimate", options={}, folder=tmp_path)
    res = run_batch(tasks, tmp_path / "out", scheduler=cluster, progress=False)
    assert marker.is_file()  # the first attempt of p-1 killed its worker
    assert [r["status"] for r in res.rows] == ["ok"] * 3
    assert [r["record"] for r in res.rows] == ["p-0", "p-1", "p-2"]


def test_cli_errors_are_one_line(tmp_path, capsys):
    assert main(["batch", "fit", str(tmp_path / "none*.csv"), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip().startswith("hosid: error: no file matches")
    design = tmp_path / "d.csv"
    design.write_text("name,a1,n1,a2,n2,S0\nx,0.5,0.5,25,5,100\n")
    argv = ["batch", "simulate-study", str(design), "--out", str(tmp_path / "o")]
    assert main([*argv, "--analysis", "diagnose", "--cost", "J4A"]) == 2
    assert "--cost does not apply to --analysis diagnose" in capsys.readouterr().err
    assert main(["batch"]) == 2
    assert not (tmp_path / "o").exists()


def test_design_entropy_names_the_streams_and_later_options_keep_ids(records, tmp_path):
    """A row's ``entropy`` gives record i the stream SeedSequence([seed, *entropy, i]) (a
    study's own streams); diagnose's later options enter the id only off their default.
    """
    rows = _design(tmp_path, "name,key,seeds,a1,a2,S0,entropy\nA,0,2,0.5,25,100,11 12\n")
    assert rows[0].entropy == (11, 12)
    t = design_tasks(rows, analysis="estimate", options={}, seed=7)[1]
    ref = np.random.SeedSequence([7, 11, 12, 1])
    np.testing.assert_array_equal(t.seed_sequence().generate_state(4), ref.generate_state(4))
    keyed = design_tasks(_design(tmp_path, "name,a1,a2,S0\nA,0.5,25,100\n"), analysis="estimate",
                         options={}, seed=7)[0]  # fmt: skip
    assert t.prepare().id != keyed.prepare().id  # the entropy is part of the id
    with pytest.raises(HosidInputError, match="entropy"):
        _design(tmp_path, "name,a1,a2,S0,entropy\nA,0.5,25,100,x\n")
    path = str(records / "r0.npz")

    def diag_id(**options):
        return record_tasks([path], analysis="diagnose", options=options)[0].prepare().id

    default = diag_id()
    assert diag_id(posterior="emcee", candidate_gaps=True) == default
    assert diag_id(posterior="screen") != default != diag_id(candidate_gaps=False)
    with pytest.raises(HosidInputError, match="option posterior of diagnose"):
        diag_id(posterior="nuts")


def test_excitation_shape_option_reads_the_table_and_keeps_old_ids(records, tmp_path, capsys):
    path = str(records / "r0.npz")
    shape = tmp_path / "shape.csv"
    w = np.linspace(0.0, 200.0, 400)
    np.savetxt(shape, np.c_[w, 49.0**2 / ((49.0 - w**2) ** 2 + (0.4 * 7.0 * w) ** 2 + 1.0)],
               delimiter=",", header="omega,level", comments="")  # fmt: skip
    default = record_tasks([path], analysis="estimate", options={})[0].prepare()
    same = record_tasks([path], analysis="estimate", options={"excitation_shape": None})[0]
    assert same.prepare().id == default.id  # a later option at its default keeps the id
    task = record_tasks([path], analysis="estimate", options={"excitation_shape": str(shape)})[0]
    task = task.prepare()
    assert task.id != default.id
    row = run_task(task, task.seed_sequence()).row
    assert row["status"] == "ok", row.get("message")
    plain = run_task(default, default.seed_sequence()).row
    assert row["S0_mean"] != plain["S0_mean"]  # the shape moved the level
    # a missing table stops the batch at once, in one line, with no output folder
    out = tmp_path / "o"
    argv = ["batch", "estimate", path, "--excitation-shape", str(tmp_path / "no.csv")]
    assert main([*argv, "--out", str(out)]) == 2
    assert "no such file" in capsys.readouterr().err and not out.exists()


def test_measured_option_declares_the_channels(tmp_path):
    """``--measured acceleration``: a CSV of accelerations (its file says nothing of what
    it holds) is estimated as the single oscillator's acceleration record, as ``hosid
    estimate --measured acceleration`` does; the option enters the task's id only when
    given.
    """
    from hosid.model.chain import simulate_chain, write_chain_record
    from hosid.model.system import System

    single = System.single("paper", hosid.PAPER_PARAMS)
    rec = simulate_chain(single, duration=600.0, dt=0.02, rng=np.random.default_rng(3),
                         measured="acceleration")  # fmt: skip
    path = str(write_chain_record(rec, tmp_path / "acc.csv"))
    plain = record_tasks([path], analysis="estimate", options={})[0].prepare()
    same = record_tasks([path], analysis="estimate", options={"measured": None})[0].prepare()
    assert same.id == plain.id
    task = record_tasks([path], analysis="estimate", options={"measured": "acceleration"})[0]
    task = task.prepare()
    assert task.id != plain.id
    row = run_task(task, task.seed_sequence()).row
    assert row["status"] == "ok", row.get("message")
    for k in ("a2", "n2"):  # within 4 of their sd of the truth
        assert abs(row[f"{k}_mean"] - hosid.PAPER_PARAMS[k]) < 4.0 * row[f"{k}_sd"], k
    with pytest.raises(HosidInputError, match="measured"):
        record_tasks([path], analysis="estimate", options={"measured": "velocity"})


def test_diagnose_with_a_system_file_locates(tmp_path):
    """``hosid batch diagnose REC --model SYSTEM.toml``: the (effect, element) pairs of
    ``hosid diagnose`` with a system file (it failed as an unknown model term).
    """
    from hosid.model.chain import simulate_chain, write_chain_record
    from hosid.model.system import System

    head = 'dofs = ["x1", "x2"]\n[[element]]\nbetween = ["ground", "x1"]\n'
    head += 'terms = ["linear_damping", "linear_stiffness"]\n[[element]]\n'
    head += 'between = ["x1", "x2"]\nterms = ["linear_damping", "linear_stiffness"'
    values = {"a1[ground-x1]": 0.3, "a2[ground-x1]": 25.0, "a1[x1-x2]": 0.2,
              "a2[x1-x2]": 15.0, "n2[x1-x2]": 10.0, "mass[x2]": 0.8, "S0[x1]": 2.0,
              "S0[x2]": 2.0}  # fmt: skip
    truth = head + ', "cubic_stiffness"]\n[values]\n'
    truth += "".join(f'"{k}" = {v}\n' for k, v in values.items())
    (tmp_path / "base.toml").write_text(head + "]\n")
    (tmp_path / "truth.toml").write_text(truth)
    system = System.from_toml(tmp_path / "truth.toml")
    rec = simulate_chain(system, duration=600.0, dt=0.02, rng=np.random.default_rng(5))
    path = str(write_chain_record(rec, tmp_path / "rec.npz"))
    opts = {"model": str(tmp_path / "base.toml")}
    task = record_tasks([path], analysis="diagnose", options=opts)[0].prepare()
    row = run_task(task, task.seed_sequence()).row
    assert row["status"] == "ok", row.get("message")
    assert row["named_effect"].split("+")[0] == "cubic_stiffness in x1-x2", row["evidence"]
    assert "n2[x1-x2]_mean" in row and "a2[ground-x1]_q95" in row

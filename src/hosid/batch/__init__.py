"""Many records, or a simulation design, through one analysis on dask.distributed.

``hosid batch`` (:mod:`hosid.batch.cli`) and its library form::

    from hosid.batch import design_tasks, read_design, record_tasks, run_batch

    tasks = record_tasks(["a.csv", "b.csv"], analysis="fit", options={"cost": "J4A"})
    result = run_batch(tasks, "out/", workers=2)          # out/results.csv
    tasks = design_tasks(read_design("design.csv"), analysis="fit", options={}, seed=1)

Modules: :mod:`~hosid.batch.tasks` (a task, its id and seed; record inputs),
:mod:`~hosid.batch.design` (design tables and their simulation),
:mod:`~hosid.batch.work` (what a worker does with one task),
:mod:`~hosid.batch.table` (row files and ``results.csv``),
:mod:`~hosid.batch.runner` (dask, resume, nothing lost).
"""

from .design import DesignRow, design_tasks, read_design
from .runner import BatchResult, dask_client, run_batch
from .table import read_results
from .tasks import DesignPoint, Task, expand_inputs, options_for, record_tasks
from .work import run_task

__all__ = [
    "BatchResult",
    "DesignPoint",
    "DesignRow",
    "Task",
    "dask_client",
    "design_tasks",
    "expand_inputs",
    "options_for",
    "read_design",
    "read_results",
    "record_tasks",
    "run_batch",
    "run_task",
]

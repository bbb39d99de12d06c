"""What the campaign tests share: a 12-run spec that takes long enough to interrupt, and
the results table without the columns that differ between two runs of one campaign."""
from __future__ import annotations

from pathlib import Path

import pyarrow.parquet as pq

#: columns that legitimately differ between two runs of the same campaign
TIMING = {"wall_s", "loop_s", "design_s", "build_s", "host", "pid"}

#: 12 runs of 40 s, one per task: long enough to stop mid-way
RESUME = """
base = "paper"
seeds = "0-5"
seeds_per_task = 1
[sweep]
"simulation.estimator" = ["kalman", "ideal"]
"simulation.T" = [40.0]
"""


def rows(out: Path, name: str = "results.parquet") -> list[dict]:
    """The rows of a campaign table."""
    return pq.read_table(out / name).to_pylist()


def without_timing(table: list[dict]) -> list[dict]:
    """The rows without the TIMING columns."""
    return [{k: v for k, v in r.items() if k not in TIMING} for r in table]

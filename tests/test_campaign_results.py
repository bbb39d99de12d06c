"""The output folder: the lock, rows kept per task and read back, Parquet tables."""
from __future__ import annotations

import json

import pyarrow.parquet as pq

from orchestrator.campaign.results import ResultStore, write_table


def _row(point, seed, key, **kw):
    row = {"run_key": key, "role": "run", "point": point, "seed": seed, "engine": "fmu",
           "status": "ok", "error": None, "params": json.dumps({"simulation.T": 5.0 + point,
                                                                "simulation.estimator": "kalman"}),
           "cost_rate": 1.5 * seed, "rms_e": [1.0, 2.0], "rms_u": [0.5, 0.25], "wall_s": 0.1}
    row.update(kw)
    return row


def test_rows_survive_and_are_read_back(tmp_path):
    store = ResultStore(tmp_path)
    store.add([_row(1, 0, "a"), _row(1, 1, "b")])
    store.add([_row(0, 2, "c", status="error", error="no design", cost_rate=None, rms_e=None,
                    rms_u=None)])
    (tmp_path / "parts" / ".x.json.abc.part").write_text("half")     # a killed writer's
    (tmp_path / "parts" / "broken.json").write_text("[{")               # never whole
    again = ResultStore(tmp_path)
    assert again.done == {"a", "b", "c"}
    assert not list((tmp_path / "parts").glob(".*.part"))
    assert [(r["point"], r["seed"]) for r in again.table_rows()] == [(0, 2), (1, 0), (1, 1)]
    again.write({"a", "c"})
    rows = pq.read_table(tmp_path / "results.parquet").to_pylist()
    assert [r["run_key"] for r in rows] == ["c", "a"]
    assert rows[0]["error"] == "no design" and rows[0]["cost_rate"] is None
    assert rows[1]["param:simulation.T"] == 6.0 and rows[1]["rms_e"] == [1.0, 2.0]
    assert rows[1]["param:simulation.estimator"] == "kalman"


def test_parameter_columns_by_type(tmp_path):
    rows = [_row(0, 0, "a", params=json.dumps({"x": 1, "y": [[1.0]], "z": True})),
            _row(1, 0, "b", params=json.dumps({"x": 2.5, "y": 3.0, "z": False}))]
    write_table(rows, tmp_path / "t.parquet")
    t = pq.read_table(tmp_path / "t.parquet")
    assert t.column("param:x").to_pylist() == [1.0, 2.5]
    assert t.column("param:y").to_pylist() == ["[[1.0]]", "3.0"]
    assert t.column("param:z").to_pylist() == [True, False]
    assert not list(tmp_path.glob(".*"))                         # written atomically

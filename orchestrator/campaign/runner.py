"""``auv-cosim campaign``: plan the runs, skip the finished ones, run the rest on Dask, keep
every finished row, write the tables, the aggregate and the plots.

The client is the only writer of the output folder and holds its lock (:mod:`.results`).
It writes into a staging folder beside it (:func:`orchestrator.outputs.staged_output`),
gathering the finished rows (``parts/``) of the folder, of ``<out>.interrupted`` and of
the staging folder a killed client left; the finished campaign is swapped in whole, an
unfinished one replaces only an unfinished one (else it goes to ``<out>.interrupted``).
Tasks (:mod:`.tasks`) go to the cluster as they are planned; each finished task's rows are
written at once (a part file, and results.parquet rewritten), so an interruption (Ctrl-C /
SIGTERM: the client cancels what is left, writes the tables, exits 130 / 143; a killed
client; a killed worker: Dask runs its task elsewhere; a lost scheduler: the client stops
after ``LOST_AFTER_S``) loses only runs in progress. Rerunning the same command skips
every run whose key is kept and does the rest.

``--engine numpy``: the points the numpy engine can run (:func:`.engine_numpy.numpy_unsupported`)
run there, vectorised over seeds; the others run through the FMUs. Then a sample of
``check`` numpy points (their first seed) is re-run through the FMUs and the two must agree
to ``CHECK_TOLERANCE`` (relative, every statistic): ``campaign.json`` says how closely.
"""
from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..analysis.summary import versions
from ..atomic import write_text_atomically
from ..exit_status import INCOMPLETE, OK, POINTS_FAILED, points_failed_line
from ..interrupt import EXIT_STATUS, stop_on_signals
from ..outputs import Staging, staged_output
from ..running.naming import campaign_out
from ..swap import CAMPAIGN
from .points import DesignPoint, resolve_points, run_key
from .results import ResultStore, unfinished_campaign
from .spec import ENGINES, FMU_ENGINE, SpecError, load_spec
from .tasks import Task, error_rows, run_task

__all__ = ["run_campaign", "plan_tasks", "split_tasks", "numpy_batches", "NUMPY_BATCH",
           "check_sample", "compare_check", "CHECK_TOLERANCE", "Progress"]

CHECK_TOLERANCE = 1e-9
#: seeds per numpy task unless the spec says (numpy_batches)
NUMPY_BATCH = 64
#: seconds without a scheduler before the client gives up (rows kept; rerun to go on)
LOST_AFTER_S = 15.0


def plan_tasks(points: list[DesignPoint], seeds: list[int], engine: str,
               ver: dict[str, str]) -> list[Task]:
    """One task per point with all its seeds, on ``engine`` where it can run.

    Parameters
    ----------
    points : list[DesignPoint]
    seeds : list[int]
    engine : str
        The requested engine ('fmu' or 'numpy').
    ver : dict[str, str]
        Package versions (in the run keys).

    Returns
    -------
    list[Task]
    """
    from .engine_numpy import numpy_unsupported
    tasks = []
    for pt in points:
        eng, note = engine, None
        if engine == "numpy" and pt.scenario is not None:
            note = numpy_unsupported(pt.coupling, pt.sections, pt.scenario)
            if note:
                eng = FMU_ENGINE
        keys = tuple(run_key(pt, s, eng, ver) for s in seeds)
        tasks.append(Task(pt.index, pt.params, pt.scenario, pt.coupling, eng, tuple(seeds),
                          keys, error=pt.error, note=note))
    return tasks


def _batches(t: Task, per: int) -> list[Task]:
    return [Task(t.point, t.params, t.scenario, t.coupling, t.engine, t.seeds[i:i + per],
                 t.keys[i:i + per], t.role, t.error, t.note)
            for i in range(0, len(t.seeds), per)]


def numpy_batches(tasks: list[Task], seeds_per_task: int | None = None) -> list[Task]:
    """The numpy engine's tasks split into fixed batches of a point's seeds (FMU tasks
    unchanged).

    A numpy batch is run as one matrix recursion, and the last bits of a product depend on
    the number of rows BLAS multiplies at once; so a batch's seeds are fixed by the spec
    alone (``seeds_per_task``, default :data:`NUMPY_BATCH`), never by the cluster's size or
    by which runs are finished, and an unfinished batch is re-run whole: the same seed
    gives the same row in every campaign.

    Parameters
    ----------
    tasks : list[Task]
    seeds_per_task : int, optional

    Returns
    -------
    list[Task]
    """
    per = seeds_per_task or NUMPY_BATCH
    return [b for t in tasks for b in (_batches(t, per) if t.engine == "numpy" else [t])]


def split_tasks(tasks: list[Task], workers: int, seeds_per_task: int | None = None) -> list[Task]:
    """Split the FMU engine's tasks into batches of seeds so that every worker has work.

    Default batch: ceil(runs / (2 workers)) seeds (two tasks per worker balance uneven
    points); never across points, so each batch solves its point's design once. Numpy
    tasks are left as they are (:func:`numpy_batches`).

    Parameters
    ----------
    tasks : list[Task]
    workers : int
    seeds_per_task : int, optional
        Fixed batch size.

    Returns
    -------
    list[Task]
    """
    total = sum(len(t.seeds) for t in tasks if t.engine == FMU_ENGINE)
    per = seeds_per_task or max(1, math.ceil(total / (2 * max(1, workers))))
    return [b for t in tasks for b in (_batches(t, per) if t.engine == FMU_ENGINE else [t])]


def check_sample(tasks: list[Task], count: int, ver: dict[str, str],
                 points: dict[int, DesignPoint]) -> list[Task]:
    """FMU re-runs of ``count`` numpy points (evenly spread), the first seed of each.

    Parameters
    ----------
    tasks : list[Task]
        The campaign's tasks.
    count : int
    ver : dict[str, str]
    points : dict[int, DesignPoint]
        By index.

    Returns
    -------
    list[Task]
    """
    numpy_points = sorted({t.point for t in tasks if t.engine == "numpy"})
    if not numpy_points or count <= 0:
        return []
    step = len(numpy_points) / min(count, len(numpy_points))
    chosen = [numpy_points[int(i * step)] for i in range(min(count, len(numpy_points)))]
    out = []
    for idx in chosen:
        t = next(t for t in tasks if t.point == idx)
        seed = min(t.seeds)
        key = run_key(points[idx], seed, FMU_ENGINE, ver, role="check")
        out.append(Task(idx, t.params, t.scenario, t.coupling, FMU_ENGINE, (seed,), (key,),
                        role="check"))
    return out


def _rel(a: float, b: float) -> float:
    return abs(a - b) / max(1.0, abs(b))


def compare_check(run_rows: list[dict], check_rows: list[dict]) -> dict[str, Any]:
    """Largest relative difference between numpy rows and their FMU re-runs.

    Compares the cost rate and every RMS component, |a - b| / max(1, |b|).

    Parameters
    ----------
    run_rows : list[dict]
        The numpy engine's rows.
    check_rows : list[dict]
        The FMU re-runs (role 'check').

    Returns
    -------
    dict[str, Any]
        ``runs`` compared, ``max_rel_diff``, ``tolerance``, ``passed``, ``points``.
    """
    by = {(r["point"], r["seed"]): r for r in run_rows if r["engine"] == "numpy"}
    worst, n, pts = 0.0, 0, []
    for c in check_rows:
        r = by.get((c["point"], c["seed"]))
        if r is None or r["status"] != "ok" or c["status"] != "ok":
            continue
        diffs = [_rel(r["cost_rate"], c["cost_rate"])] + [
            _rel(a, b) for k in ("rms_e", "rms_u") for a, b in zip(r[k], c[k])]
        worst = max(worst, max(diffs))
        n += 1
        pts.append(c["point"])
    return {"runs": n, "points": pts, "max_rel_diff": worst, "tolerance": CHECK_TOLERANCE,
            "passed": n > 0 and worst <= CHECK_TOLERANCE}


class Progress:
    """Counts finished runs: a tqdm bar when stderr is a terminal, else a plain line at
    every tenth of the runs (and at most every 30 s between)."""

    def __init__(self, total: int, enabled: bool | None = None):
        self.total, self.done, self.failed = total, 0, 0
        self.t0 = self._last = time.monotonic()
        self._next = max(1, total // 10)
        tty = sys.stderr.isatty() if enabled is None else enabled
        self.bar = None
        if tty and total:
            from tqdm import tqdm
            self.bar = tqdm(total=total, unit="run", file=sys.stderr, leave=False)

    def add(self, rows: list[dict]) -> None:
        """Count one task's rows."""
        self.done += len(rows)
        self.failed += sum(r["status"] != "ok" for r in rows)
        if self.bar is not None:
            self.bar.update(len(rows))
            self.bar.set_postfix(failed=self.failed, refresh=False)
            return
        now = time.monotonic()
        if self.done >= self._next or now - self._last > 30 or self.done == self.total:
            print(f"campaign: {self.done}/{self.total} runs ({self.failed} failed), "
                  f"{now - self.t0:.0f} s", file=sys.stderr, flush=True)
            self._last = now
            while self._next <= self.done:
                self._next += max(1, self.total // 10)

    def write(self, text: str) -> None:
        """A line that does not break the bar."""
        if self.bar is not None:
            self.bar.write(text, file=sys.stderr)
        else:
            print(text, file=sys.stderr, flush=True)

    def close(self) -> None:
        """Remove the bar."""
        if self.bar is not None:
            self.bar.close()


def _run_on_cluster(client: Any, tasks: list[Task], store: ResultStore, progress: Progress,
                    stop: Any, keys: set[str]) -> dict[str, Any]:
    """Submit ``tasks``, keep each finished task's rows as it arrives; returns counts."""
    from dask.distributed import as_completed

    futures = [client.submit(run_task, t, pure=False, key=f"campaign-{t.role}-{t.point}-"
                             f"{t.keys[0][:12]}") for t in tasks]
    ac = as_completed(futures)
    lost: list[str] = []
    unreachable_since: float | None = None
    while not ac.is_empty():
        if stop:
            break
        batch = ac.next_batch(block=False)
        if not batch:
            if client.status != "running":
                unreachable_since = unreachable_since or time.monotonic()
                if time.monotonic() - unreachable_since > LOST_AFTER_S:
                    lost.append(f"lost the scheduler (client {client.status})")
                    break
            else:
                unreachable_since = None
            time.sleep(0.1)
            continue
        for fut in batch:
            try:
                rows = fut.result()
            except Exception as exc:                   # a killed worker, a lost scheduler
                lost.append(f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:300])
                continue
            store.add(rows)
            store.write(keys)
            progress.add(rows)
    pending = [f for f in futures if not f.done()]
    if pending:
        try:
            client.cancel(pending)
        except Exception:
            pass
    return {"lost": lost, "not_run": len(pending)}


def run_campaign(spec_path: Path | str, out: Path | str | None = None, *,
                 scheduler: str | None = None, workers: int | None = None,
                 engine: str | None = None, progress: bool | None = None,
                 log: Callable[[str], None] = print, fmus: str | None = None) -> int:
    """Run a campaign (module docstring) and print a table of its points.

    Parameters
    ----------
    spec_path : Path or str
        The campaign spec (:mod:`.spec`).
    out : Path or str, optional
        Output folder (default ``out/campaign_<name>``, the name cleaned:
        :func:`orchestrator.running.naming.campaign_out`).
    scheduler : str, optional
        Address of a Dask scheduler; default a local cluster.
    workers : int, optional
        Worker processes of the local cluster (default one per core).
    engine : str, optional
        'fmu' or 'numpy' (default: the spec's).
    progress : bool, optional
        Progress bar (default: when stderr is a terminal; else plain lines).
    log : callable, optional
        Receives the lines of the report.
    fmus : str, optional
        'python' or 'native': the base scenario's ``[simulation] fmus`` for every point
        that does not sweep it (``--fmus``).

    Returns
    -------
    int
        (:mod:`orchestrator.exit_status`) 0 when every run of every point ran; 130 / 143
        when stopped by SIGINT / SIGTERM; else 1 if runs were lost or the numpy check
        failed; else 3 if some points (or all) are error rows, counted in one line on
        stderr.

    Raises
    ------
    SpecError
        Bad spec, an unreachable scheduler.
    OutputFolderError
        The output folder is in use or cannot be written.
    """
    t_start = time.perf_counter()
    spec, seeds, base, base_where = load_spec(spec_path)
    if fmus is not None:
        base.setdefault("simulation", {})["fmus"] = fmus
        base_where += f" (--fmus {fmus})"
    if engine is not None and engine not in ENGINES:
        raise SpecError(f"--engine {engine!r} is not one of {', '.join(ENGINES)}")
    if scheduler and workers:
        raise SpecError("--workers sets the size of the local cluster; with --scheduler the "
                        "cluster's own workers run the tasks")
    engine = engine or spec.engine
    name = spec.name or Path(spec_path).stem
    out = Path(out) if out else campaign_out(name)     # the name cleaned: never outside out/
    with staged_output(out, "campaign", force=None, kind=CAMPAIGN,
                       replaceable=unfinished_campaign, resume=("parts",)) as st, \
            stop_on_signals() as stop:
        points = resolve_points(spec, base, base_where)
        ver = versions()
        tasks = plan_tasks(points, seeds, engine, ver)
        by_index = {p.index: p for p in points}
        checks = check_sample(tasks, spec.check, ver, by_index) if engine == "numpy" else []
        keys = {k for t in tasks + checks for k in t.keys}
        store = ResultStore(st.path)
        done_before = len(keys & store.done)
        for t in tasks:                                # points without a scenario: rows now
            if t.scenario is None and (p := t.pending(store.done)):
                store.add(error_rows(p, p.error or "invalid point"))
        todo = []
        for t in numpy_batches(tasks, spec.seeds_per_task) + checks:
            if t.scenario is None:
                continue
            if t.engine == "numpy":             # unfinished: whole (numpy_batches says why)
                todo += [t] if set(t.keys) - store.done else []
            elif p := t.pending(store.done):
                todo.append(p)
        total = sum(len(t.seeds) for t in tasks)
        log(f"campaign {name}: {len(points)} point(s) x {len(seeds)} seed(s) = {total} runs "
            f"(+{len(checks)} check) of {base_where}, engine {engine}; "
            f"{done_before} already done, {sum(len(t.seeds) for t in todo)} to run")
        bar = Progress(sum(len(t.seeds) for t in todo), progress)
        result: dict[str, Any] = {"lost": [], "not_run": 0}
        cluster_info: dict[str, Any] = {"scheduler": scheduler, "workers": 0}
        try:
            if todo:
                from .cluster import dask_client, worker_count
                with dask_client(scheduler, workers) as client:
                    n = worker_count(client)
                    cluster_info["workers"] = n
                    run_tasks = split_tasks([t for t in todo if t.role == "run"], n,
                                            spec.seeds_per_task)
                    t_tasks = time.perf_counter()
                    result = _run_on_cluster(client, run_tasks + [t for t in todo
                                                                  if t.role == "check"],
                                             store, bar, stop, keys)
                    cluster_info["tasks"] = len(run_tasks) + len(checks)
                    cluster_info["tasks_wall_s"] = time.perf_counter() - t_tasks
        finally:
            bar.close()
        store.write(keys)
        return _report(st, name, spec, engine, store, keys, tasks, checks, result, stop,
                       cluster_info, time.perf_counter() - t_start, log)


def _report(st: Staging, name: str, spec: Any, engine: str, store: ResultStore, keys: set[str],
            tasks: list[Task], checks: list[Task], result: dict[str, Any], stop: Any,
            cluster_info: dict[str, Any], wall_s: float, log: Callable[[str], None]) -> int:
    from .aggregate import write_aggregate
    from .plot import write_plots

    rows = store.table_rows("run", keys)
    agg = write_aggregate(rows, st.path)
    plots = write_plots(agg, st.path)
    check = compare_check(rows, store.table_rows("check", keys)) if checks else None
    total = sum(len(t.seeds) for t in tasks)
    missing = total - len(rows)
    failed = _failed_points(rows)
    summary = {
        "campaign": name, "spec": spec.model_dump(), "engine": engine, "runs": total,
        "rows": len(rows), "failed": sum(r["status"] != "ok" for r in rows),
        "failed_points": len(failed),
        "missing": missing, "interrupted_by": stop.name, "lost": result["lost"],
        "numpy_check": check, "cluster": cluster_info, "wall_s": wall_s,
        "plots": [p.name for p in plots], "versions": versions(),
    }
    write_text_atomically(st.path / "campaign.json", json.dumps(summary, indent=2))
    # complete: replaces the earlier result; unfinished: replaces an unfinished one (or
    # goes beside a finished one, to <out>.interrupted), and the next run resumes it
    out = st.finish(complete=not (stop or result["lost"] or missing))
    for a in agg:
        params = ", ".join(f"{k}={v}" for k, v in json.loads(a["params"]).items()) or "base"
        if a["ok"] and a.get("cost_rate_mean") is None:
            log(f"  [{a['point']}] {params}: {a['ok']} ok, no cost rate (empty statistics "
                "window: T too short)")
        elif a["ok"]:
            pred = a["predicted_cost_rate"]
            log(f"  [{a['point']}] {params}: cost rate {a['cost_rate_mean']:.4g} "
                f"[{a['cost_rate_ci_low']:.4g}, {a['cost_rate_ci_high']:.4g}] predicted "
                f"{'-' if pred is None else format(pred, '.4g')} "
                f"({a['ok']} ok, {a['failed']} failed, {a['engines']})")
        else:
            log(f"  [{a['point']}] {params}: failed ({a['failed']} runs): {a['error']}")
    log(f"{len(rows)} of {total} runs in {out / 'results.parquet'} "
        f"({summary['failed']} failed), aggregate in {out / 'aggregate.parquet'}, "
        f"{wall_s:.1f} s")
    if check is not None:
        log(f"numpy engine against the FMUs on {check['runs']} run(s): largest relative "
            f"difference {check['max_rel_diff']:.2e} (tolerance {CHECK_TOLERANCE:g}): "
            f"{'agree' if check['passed'] else 'DISAGREE'}")
    if failed:
        print(points_failed_line(
            "campaign", len(failed), len(tasks),
            f"{summary['failed']} of {len(rows)} runs are error rows in "
            f"{out / 'results.parquet'}", f"point {failed[0][0]}: {failed[0][1]}"),
            file=sys.stderr)
    if stop:
        print(f"auv-cosim campaign: interrupted by {stop.name}: {len(rows)} of {total} runs "
              f"kept in {out / 'results.parquet'}; rerun the same command to finish"
              + (f"; {st.note}" if st.note else ""), file=sys.stderr)
        return EXIT_STATUS[stop.name]
    if result["lost"] or missing:
        print(f"auv-cosim campaign: {missing} run(s) not done ({'; '.join(result['lost'][:3])})"
              f"; rerun the same command to do them" + (f"; {st.note}" if st.note else ""),
              file=sys.stderr)
        return INCOMPLETE
    if check is not None and not check["passed"]:
        return INCOMPLETE
    return POINTS_FAILED if failed else OK


def _failed_points(rows: list[dict]) -> list[tuple[int, str]]:
    """The points with an error row, in order, each with its first row's reason."""
    first: dict[int, str] = {}
    for r in rows:
        if r["status"] != "ok" and r["point"] not in first:
            first[r["point"]] = r["error"] or "no reason given"
    return sorted(first.items())

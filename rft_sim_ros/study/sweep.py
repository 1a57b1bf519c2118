"""`rft-sim sweep`: run every run of a study on a backend (local processes or Ray), record
each as it finishes, and write the results table and plots.

Output folder:
  study.yaml             the study as given (for the record)
  runs/<id>/summary.json each run: `study_run` (varied values, overrides, repeat,
                         wall_time_s, stable, reason, worker, the SHA-256 of each file
                         it reads: `file_digests`) and `summary` (run_scene's
                         summary.json content, null if the run raised); written
                         atomically as the run finishes: the source of truth for --resume
  results.csv            one row per run (see table.py), results.npz the same, columnar
  plots/                 each metric against each varied key
  study.json             counts, wall time, backend, workers, machine
  report.html            the study's page: table, plots, a link to each run's page
                         (runs/<id>/report.html); study/page.py
"""
import functools
import hashlib
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import yaml

from ..sand.grid_memory import MEMORY_FRACTION, machine_memory
from ..sim.runner import machine_info
from ..sim.summary import json_default
from . import plots, table
from .cost import dearest_first
from .execute import RunTask, execute, failure_record
from .pool import default_workers, map_unordered
from .page import write_study_page
from .progress import StudyProgress
from .spec import StudyError

#: Least time between two rewrites of results.csv while runs finish, s.
TABLE_EVERY_S = 2.0


@dataclass
class StudyResult:
    """rows: the table rows in run order; records: {run_id: record} of the runs executed
    now (see execute); ran / failed: runs executed this time and how many
    of all rows are not stable; resumed: runs found finished on disk; wall_s: this session;
    warm_s: time the workers spent warming up (s, summed); outputs_s: writing the final
    table and plots (s); backend: where the runs ran."""
    rows: list
    records: dict
    ran: int
    resumed: int
    failed: int
    wall_s: float
    warm_s: float
    outputs_s: float
    backend: str
    plots: list


def _summary_path(out, run_id):
    return Path(out) / 'runs' / run_id / 'summary.json'


#: Distinct run notices a study logs before it only counts them (`RunNotices`).
SHOWN_NOTICES = 10


def _same(a, b):
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def file_digests(paths):
    """{path: SHA-256 (hex)} of the files at `paths` (a run's `files`: the scene file, the
    model, a grid, a zeta map), so that a resumed study redoes a run whose files changed
    since it ran; a file gone since is missing from it."""
    found = {}
    for path in paths:
        try:
            info = os.stat(path)
        except OSError:
            continue
        found[path] = _digest(path, info.st_mtime_ns, info.st_size)
    return found


@functools.lru_cache(maxsize=256)
def _digest(path, mtime_ns, size):
    """SHA-256 (hex) of the file at `path` as it is at (mtime_ns, size): read once per state."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def finished_records(out, study, retry_failed=False):
    """{run_id: record} of the study's runs already on disk with the same overrides and the
    same files (a run whose summary is missing, unreadable, for other values or for files
    changed since is not finished)."""
    records = {}
    for run in study.runs:
        try:
            saved = json.loads(_summary_path(out, run.run_id).read_text())
        except (OSError, ValueError):
            continue
        mark = saved.get('study_run') or {}
        if not _same(mark.get('overrides'), run.overrides) or mark.get('repeat') != run.repeat:
            continue
        if 'files' in mark and mark['files'] != file_digests(run.files):
            continue
        if retry_failed and not mark.get('stable'):
            continue
        records[run.run_id] = {**{k: mark.get(k) for k in ('stable', 'reason', 'worker')},
                               'wall_time_s': mark.get('wall_time_s'), 'warm_s': 0.0,
                               'run_id': run.run_id, 'summary': saved.get('summary')}
    return records


def _save(out, run, record):
    content = {'study_run': {
        'run_id': run.run_id, 'varied': run.varied, 'repeat': run.repeat,
        'overrides': run.overrides, 'files': file_digests(run.files),
        'wall_time_s': record['wall_time_s'],
        'warm_s': record.get('warm_s'), 'started_at': record.get('started_at'),
        'finished_at': record.get('finished_at'),
        'stable': record['stable'], 'reason': record['reason'], 'worker': record['worker']},
        'summary': record['summary']}
    path = _summary_path(out, run.run_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    table.write_atomic(path, json.dumps(content, indent=1, default=json_default).encode())


def workers_within_memory(runs, workers, log):
    """At most `workers`, and as many as can hold the largest deformable beds of `runs` at
    once (one a worker) within MEMORY_FRACTION of this machine's memory, said through `log`
    where that is fewer (each bed alone was checked against it as the study loaded)."""
    memory = machine_memory()
    largest = sorted((run.bed_bytes for run in runs), reverse=True)
    fit = workers
    while memory is not None and fit > 1 and sum(largest[:fit]) > MEMORY_FRACTION * memory:
        fit -= 1
    if fit < workers:
        log(f'deformable beds of up to {largest[0] / 2**30:.3g} GiB: {fit} of {workers} '
            f'workers at once keep them within half of this machine\'s {memory / 2**30:.3g} '
            'GiB')
    return fit


class RunNotices:
    """What the runs' start-up and run notices say (summary.json's `notices`: a bed the
    robot walks off, cells wider than a foot, a base that avalanches), each distinct text
    logged once with the first run that said it, SHOWN_NOTICES at most, then how many more
    there were (every run's are in its summary.json)."""

    def __init__(self, log):
        self._log, self._said, self._more = log, set(), 0

    def say(self, run_id, notices):
        for notice in notices:
            if notice in self._said:
                continue
            self._said.add(notice)
            if len(self._said) <= SHOWN_NOTICES:
                self._log(f'run {run_id}: {notice}')
            else:
                self._more += 1

    def close(self):
        if self._more:
            self._log(f'{self._more} more distinct notices: see runs/<id>/summary.json')


def run_study(study, out, workers=None, ray=None, resume=False, retry_failed=False,
              run_timeout=None, progress=True, log=lambda line: None):
    """Run `study` (spec.Study) into folder `out`: on `workers` local processes (default: all
    cores) or, when `ray` is an address, on that Ray cluster (see ray_backend). resume: keep
    the runs already finished in `out` (retry_failed: except those not stable); run_timeout:
    s per run (None: no limit). Returns a StudyResult."""
    out = Path(out)
    if (out / 'runs').is_dir() and any((out / 'runs').iterdir()) and not resume:
        raise StudyError(f'{out} already holds a study: pass --resume to finish it, or '
                         'choose another --out')
    out.mkdir(parents=True, exist_ok=True)
    table.write_atomic(out / 'study.yaml', yaml.safe_dump(study.source, sort_keys=False).encode())
    started = time.perf_counter()
    records = finished_records(out, study, retry_failed) if resume else {}
    resumed = len(records)
    todo = [run for run in study.runs if run.run_id not in records]
    todo = [todo[i] for i in dearest_first([run.cost for run in todo])]
    by_id = {run.run_id: run for run in study.runs}
    tasks = [RunTask(run.run_id, study.scene, run.overrides, study.duration, run_timeout)
             for run in todo]
    if ray is not None:
        from . import ray_backend
        outcomes = ray_backend.map_unordered(execute, tasks, ray)
        backend = f'ray ({ray})'
    else:
        workers = workers_within_memory(todo, workers or default_workers(), log)
        hard = None if run_timeout is None else 2 * run_timeout + 30
        outcomes = map_unordered(execute, tasks, workers, hard_timeout=hard)
        count = min(workers, max(1, len(tasks)))
        backend = f'local ({count} worker{"s" if count > 1 else ""})'
    log(f'{len(study.runs)} runs: {resumed} finished before, {len(tasks)} to run on {backend}')
    bar = StudyProgress(len(tasks), enabled=progress)
    names = table.columns(study)
    done = failed = 0
    warm_s = 0.0
    executed = {}
    notices = RunNotices(log)
    last_table = time.monotonic()
    try:
        for outcome in outcomes:
            run_id = tasks[outcome.index].run_id
            record = outcome.value if outcome.error is None else failure_record(
                run_id, outcome.error)
            records[run_id] = executed[run_id] = record
            warm_s += record['warm_s']
            _save(out, by_id[run_id], record)
            done += 1
            failed += not record['stable']
            if not record['stable']:
                log(f'run {run_id} {by_id[run_id].varied}: {record["reason"]}')
            notices.say(run_id, (record['summary'] or {}).get('notices', ()))
            bar.update(done, failed)
            if time.monotonic() - last_table > TABLE_EVERY_S:
                table.write_csv(out / 'results.csv', names, _rows(study, records))
                last_table = time.monotonic()
    finally:
        bar.close()
    notices.close()
    finishing = time.perf_counter()
    rows = _rows(study, records)
    table.write_csv(out / 'results.csv', names, rows)
    table.write_npz(out / 'results.npz', names, rows)
    names_written = plots.plot_study(out, study, rows)
    result = StudyResult(rows=rows, records=executed, ran=done, resumed=resumed,
                         failed=sum(not r['stable'] for r in rows),
                         wall_s=time.perf_counter() - started, warm_s=warm_s,
                         outputs_s=time.perf_counter() - finishing, backend=backend,
                         plots=names_written)
    missing = [m for m in study.metrics if all(r[m] is None for r in rows if r['stable'])]
    if missing:
        stable = next((r for r in records.values() if r['stable']), None)
        values = table.summary_values(stable.get('summary')) if stable else {}
        known = sorted(table.summary_metrics(stable.get('summary'))) if stable else []
        lists = [f'{m} is a list: name one of its numbers, {m}[0] .. {m}[{len(values[m]) - 1}]'
                 for m in missing if isinstance(values.get(m), list) and values[m]]
        log(f'no stable run reported {missing}: check the metric names'
            + ''.join(f'; {line}' for line in lists)
            + (f' (a run reports: {", ".join(known)})' if known else ''))
    table.write_atomic(out / 'study.json', json.dumps({
        'scene': study.scene, 'runs': len(study.runs), 'ran': done, 'resumed': resumed,
        'failed': result.failed, 'wall_time_s': result.wall_s, 'backend': backend,
        'missing_metrics': missing, 'machine': machine_info()}, indent=2).encode())
    write_study_page(out, study, rows, names_written)
    return result


def _rows(study, records):
    return [table.row(study, run, records[run.run_id])
            for run in study.runs if run.run_id in records]

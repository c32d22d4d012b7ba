"""
Grade nodes against scenario files: run each scenario's seeds and judge its criteria.

``python -m sim_bridge.grade scenarios/`` runs every scenario in the folder through the
runner (``sim_bridge.runner.run.run_simulation``, real rclpy), each run in a child process of its
own bounded in time and memory (:mod:`sim_bridge.grading.isolate`), shows a progress bar over the
batch, prints a pass/fail table with what was measured per criterion, writes ``report.json``,
``report.html`` and each run's outputs (metrics, plot, recording, log) below ``--out``, and
exits non-zero when any run fails. ``--node-override path/to/student.py`` grades someone
else's node on the same scenarios; ``--submissions DIR`` grades a whole class
(:mod:`sim_bridge.grading.class_batch`), ``--submission DIR`` one student's folder the same way,
and ``--gradescope results.json`` writes Gradescope's results too
(:mod:`sim_bridge.grading.gradescope`); the scenarios' marks (:mod:`sim_bridge.grading.marks`) are
in the summary line and every report. A second invocation with the same ``--out`` resumes: runs
already finished with the same inputs are not run again. See :mod:`sim_bridge.grading.scenario` for
the scenario format.
"""

import argparse
from collections.abc import Callable, Iterable, Iterator
import contextlib
import os
from pathlib import Path
import signal
import sys
import sysconfig
import tempfile
from typing import Any, IO, Sequence

from sim_bridge.common.errors import RunError
from sim_bridge.common.paths import output_folder, repo_root
from sim_bridge.common.text import PathNames, printable
from sim_bridge.grading import class_batch as grade_class, gradescope, html_report, marks
from sim_bridge.grading.batch import BatchProgress, format_table, grade_runs, summary
from sim_bridge.grading.grader_state import lock_out, OutInUse
from sim_bridge.grading.limits import (
    BUDGET_BASE_S, BUDGET_PER_SIM_S, check_memory_limit, DEFAULT_MEMORY_BYTES, DEFAULT_STALL_S,
    Limits)
from sim_bridge.grading.runs import (
    GradeJob, PAGE_NAME, REPORT_NAME, reuse_notes, RunReport, write_outputs, write_report)
from sim_bridge.grading.scenario import load_scenarios, Scenario, with_node_overrides
from sim_bridge.media.video import render_video, VIDEO_NAME, VideoError
from sim_bridge.runner.boundary.outside.node_sandbox import (
    isolation_line, isolation_warning, node_limits, say_isolation)
from sim_bridge.runner.options import started_world
from sim_bridge.simulation.world import World, WorldError


DEFAULT_OUT = Path('out') / 'grade'
#: The kit's folder: the source checkout, or the folder its package is installed in.
KIT_ROOT = repo_root() or Path(__file__).resolve().parents[1]


def report_names(out: Path, submissions: Path | None = None,
                 scenarios: Iterable[Path] = ()) -> PathNames:
    """
    Return how reports name the grader's paths: relative to ``out`` and ``submissions``.

    The paths in the folders of the ``scenarios`` files and the current folder are relative
    to them too, the home folder's start with ``~``, the Python installation's with
    ``<python>``, the kit's with ``<kit>`` and the temporary folder's (the runs' scratch
    folders) with ``<tmp>``: a report handed to a student carries none of the instructor's
    absolute paths.
    """
    folders: dict[str | os.PathLike, str] = {out: ''}
    if submissions is not None:
        folders[submissions] = ''
    folders.update({path.parent: '' for path in scenarios})
    folders.update({os.getcwd(): '', os.path.expanduser('~'): '~',
                    tempfile.gettempdir(): '<tmp>', KIT_ROOT: '<kit>'})
    for key in ('purelib', 'platlib', 'stdlib', 'platstdlib'):
        folders.setdefault(sysconfig.get_path(key), '<python>')
    folders.setdefault(sys.prefix, '<python>')
    return PathNames(folders)


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser of the grader."""
    parser = argparse.ArgumentParser(
        prog='./lab grade',
        description='Run scenario files in the simulator and judge their criteria.')
    parser.add_argument('scenarios', nargs='+', metavar='SCENARIO',
                        help='a scenario file, or a folder of them (e.g. scenarios/)')
    parser.add_argument('--node-override', action='append', default=[], metavar='TARGET',
                        help='run TARGET (a console script, module or path.py[:Class]) instead '
                        "of the scenario's node of the same name (or its only node); "
                        'NODE=TARGET replaces node NODE only; repeatable')
    parser.add_argument('--submissions', type=Path, metavar='DIR',
                        help='grade a class: DIR holds one folder per student with node files '
                        "named as the lab names them (wall_follow.py, ...); each scenario's "
                        "node is replaced by the student's file of the same name")
    parser.add_argument('--submission', type=Path, metavar='DIR',
                        help="grade one student's folder as --submissions grades each: each "
                        "scenario's node is replaced by DIR's file of the same name")
    parser.add_argument('--gradescope', type=Path, metavar='RESULTS_JSON',
                        help="also write Gradescope's results.json (marks as the score, a test "
                        'per scenario); written even when the grading fails')
    parser.add_argument('--out', type=output_folder, default=DEFAULT_OUT, metavar='DIR',
                        help=f'folder for {REPORT_NAME}, {PAGE_NAME} and the outputs of each '
                        f'run (default {DEFAULT_OUT}); the same folder again resumes')
    parser.add_argument('--jobs', type=int, default=1, metavar='N',
                        help='runs at once, each in its own process (default 1)')
    parser.add_argument('--timeout', type=float, metavar='S',
                        help='wall-clock seconds a run may take (default '
                        f'{BUDGET_BASE_S:g} + {BUDGET_PER_SIM_S:g} per simulated second)')
    parser.add_argument('--stall-timeout', type=float, default=DEFAULT_STALL_S, metavar='S',
                        help='wall-clock seconds a run may go without simulated time passing '
                        f'(a node stuck in a callback; default {DEFAULT_STALL_S:g})')
    parser.add_argument('--memory-limit', type=float, default=DEFAULT_MEMORY_BYTES / 2 ** 30,
                        metavar='GIB', help="memory of each run's nodes, in GiB (default "
                        f'{DEFAULT_MEMORY_BYTES / 2 ** 30:g}, at least 0.25)')
    parser.add_argument('--fresh', action='store_true',
                        help='run everything again, even runs finished by an earlier invocation')
    parser.add_argument('--quiet', action='store_true',
                        help='no progress; the table lists failures only')
    parser.add_argument('--no-record', action='store_true', help='skip the rosbag2 recordings')
    parser.add_argument('--no-plot', action='store_true', help='skip the trajectory plots')
    parser.add_argument('--video', action='store_true',
                        help="write each run's video (video.mp4 in its folder, played from the "
                             'report pages; needs the recordings)')
    parser.add_argument('--names', default=None,
                        help="the names on the videos (default: the student's folder with "
                             '--submissions, else none)')
    return parser


def limits_from(args: argparse.Namespace) -> Limits:
    """Return the run limits the command line asks for; ValueError names a bad one."""
    for name in ('timeout', 'stall_timeout', 'memory_limit'):
        value = getattr(args, name)
        if value is not None and not 0 < value < float('inf'):
            raise ValueError(f"--{name.replace('_', '-')} must be a positive number, got {value}")
    memory_bytes = round(args.memory_limit * 2 ** 30)
    check_memory_limit(memory_bytes, f'--memory-limit {args.memory_limit:g} GiB')
    return Limits(args.timeout, args.stall_timeout, memory_bytes)


def check_options(args: argparse.Namespace) -> None:
    """Raise ValueError, saying why, when the command line's options do not go together."""
    if args.jobs < 1:
        raise ValueError('--jobs must be at least 1')
    if args.submission is not None and args.submissions is not None:
        raise ValueError('--submission grades one student and --submissions a class: '
                         'give one of them')
    if args.gradescope is not None and args.submissions is not None:
        raise ValueError("--gradescope writes one submission's results: grade it with "
                         '--submission DIR, not --submissions')
    if args.submission is not None and not args.submission.is_dir():
        raise ValueError(f'--submission {args.submission}: not a folder')
    if args.video and args.no_record:
        raise ValueError('--video is made from the recordings: drop --no-record')


def main(argv: list[str] | None = None) -> int:
    """Grade the scenarios named on the command line; return its exit status (see status)."""
    args = build_parser().parse_args(argv)
    if not first_gradescope_results(args):
        return 2
    try:
        check_options(args)
        limits = limits_from(args)
        scenarios = load_scenarios(args.scenarios)
        scenarios = with_node_overrides(scenarios, args.node_override)
        out_lock = locked_out(args.out)  # held until the grader ends
        batch = (grade_class.ClassBatch(scenarios, args.submissions, args.out)
                 if args.submissions is not None else None)
    except (ValueError, OSError) as error:
        print(f'error: {error}', file=sys.stderr)
        failed_gradescope(args, str(error))
        return 2
    isolation = isolation_line(node_limits(0.0, limits.address_space_bytes))
    try:
        say_isolation(isolation)
    except OSError:  # stderr closed: nothing to say it on
        pass
    jobs, missing, file_notes = batch_jobs(args, scenarios, batch)
    names = report_names(args.out, args.submissions or args.submission,
                         [scenario.path for scenario in scenarios if scenario.path])
    progress = (gradescope.GradescopeProgress(jobs, missing, scenarios, args.gradescope, names,
                                              enabled=not args.quiet)
                if args.gradescope is not None else
                BatchProgress(len(jobs), sum(job.run.scenario.duration_s for job in jobs),
                              enabled=not args.quiet))
    with interrupted_as_ctrl_c() as interrupted_by:
        try:
            reports = grade_runs(jobs, workers=args.jobs, limits=limits, progress=progress,
                                 resume=not args.fresh, names=names, quiet=False,
                                 record=not args.no_record, plot=not args.no_plot)
            if args.video:
                write_videos(jobs, reports, args.names, progress.note)
            # Still interruptible: the reports are written again from the runs' saved results.
            warning = isolation_warning(isolation)
            status = write_reports(args, batch, in_scenario_order(reports, missing, scenarios),
                                   names, scenarios, [*([warning] if warning else []),
                                                      *file_notes])
            return max(status, 1) if progress.faults else status
        except KeyboardInterrupt:
            return stopped(progress, len(jobs), interrupted_by[0])
        except Exception as error:  # noqa: B902 a grader's bug still leaves Gradescope a grade
            failed_gradescope(args, f'the grader failed: {type(error).__name__}: {error}')
            raise
        finally:
            out_lock.close()


def first_gradescope_results(args: argparse.Namespace) -> bool:
    """
    Write Gradescope's results of a grading that did not finish, if asked; False if it cannot.

    Written first and replaced at the end: Gradescope always finds a grade, even when this
    process is killed on the way.
    """
    if args.gradescope is None:
        return True
    try:
        gradescope.write_results(args.gradescope, gradescope.failed_results(
            'the grading did not finish (stopped, or out of time or memory)'))
    except OSError as error:
        print(f'error: --gradescope {args.gradescope}: {error.strerror or error}',
              file=sys.stderr)
        return False
    return True


@contextlib.contextmanager
def interrupted_as_ctrl_c() -> Iterator[list[int]]:
    """
    Make SIGTERM and SIGHUP interrupt as Ctrl-C does, while in the block; yield which did.

    SIGTERM (kill, a CI job's timeout) and SIGHUP (the terminal or the ssh session closed)
    raise KeyboardInterrupt; the list yielded then holds the signal's number (SIGINT for
    Ctrl-C), so the exit status can say which it was, 128 + the number, as a shell's for a
    process killed by it. A SIGHUP ignored (nohup) stays ignored.
    """
    interrupted_by = [signal.SIGINT]

    def terminate(signum: int, frame: Any) -> None:
        interrupted_by[0] = signum
        raise KeyboardInterrupt

    previous = {signum: signal.signal(signum, terminate)
                for signum in (signal.SIGTERM, signal.SIGHUP)
                if signal.getsignal(signum) is not signal.SIG_IGN}
    try:
        yield interrupted_by
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def in_scenario_order(reports: list[RunReport], missing: list[RunReport],
                      scenarios: list[Scenario]) -> list[RunReport]:
    """Return one submission's run ``reports`` and its ``missing`` in the scenarios' order."""
    if not missing:  # as the batch has them (a class's: its batch's order)
        return reports
    order = {scenario.name: index for index, scenario in enumerate(scenarios)}
    return sorted(reports + missing, key=lambda report: (
        order[report.run.scenario.name], report.run.scenario.seeds.index(report.run.seed)))


def stopped(progress: BatchProgress, jobs: int, signum: int) -> int:
    """Say that the grading was stopped by ``signum`` and return its exit status, 128 + it."""
    why = f'the grading was stopped after {progress.done} of {jobs} runs'
    if isinstance(progress, gradescope.GradescopeProgress):  # the finished runs' tests
        progress.write_results(why, stopped=True)
    try:
        print(f'\ninterrupted: {progress.done} of {jobs} runs finished; the same '
              'command again resumes from there', file=sys.stderr)
    except OSError:  # the terminal that was closed (SIGHUP)
        pass
    return 128 + signum


def locked_out(out: Path) -> IO[bytes]:
    """Return ``out``'s lock, taken (see lock_out); ValueError says in one line why it is not."""
    try:
        return lock_out(out)
    except OutInUse as error:
        raise ValueError(str(error)) from None
    except OSError as error:
        raise ValueError(f'--out {out}: cannot write: {error.strerror or error}') from None


def batch_jobs(args: argparse.Namespace, scenarios: list[Scenario],
               batch: grade_class.ClassBatch | None) -> grade_class.SubmissionRuns:
    """
    Return the runs to grade, the failed runs of a submission's missing files and its notes.

    A class's missing files and notes are its batch's (:class:`grade_class.ClassBatch`).
    """
    if batch is not None:
        return grade_class.SubmissionRuns(batch.jobs, [], [])
    if args.submission is not None:
        return grade_class.submission_runs(scenarios, args.submission.resolve(), args.out,
                                           args.submission.resolve().name or 'submission')
    return grade_class.SubmissionRuns([GradeJob(run, args.out / run.name) for scenario in
                                       scenarios for run in scenario.runs()], [], [])


def failed_gradescope(args: argparse.Namespace, why: str) -> None:
    """Write Gradescope's results of a grading that failed (0 and why), if asked for."""
    if args.gradescope is None:
        return
    names = report_names(args.out, args.submission)  # the student reads it: none of our paths
    try:
        gradescope.write_results(args.gradescope, gradescope.failed_results(names(why)))
    except OSError as error:
        print(f'error: cannot write {printable(os.fspath(args.gradescope))}: '
              f'{error.strerror or error}', file=sys.stderr)


def write_videos(jobs: list[GradeJob], reports: list[RunReport], names: str | None,
                 note: Callable[[str], None]) -> None:
    """
    Write the video of each run that left its outputs (``video.mp4`` in its folder).

    Rendered here, after the runs, not in their children: it is the grader's code, bounded by
    nothing a student's run is. The world is the scenario's, its robot at the scenario's start
    (a 'mirrored' start turned round), and the length what the run's report (``reports``, one
    per job) says it simulated, at most the scenario's duration: nothing a run could have
    written in its folder decides what the grader loads or how many frames it draws. A video
    already newer than its run's metrics is kept; one that cannot be made is a note, not a
    failed run. ``names``: the banner's text (default: the student's name, the first part of a
    class batch's job label).
    """
    worlds: dict[tuple[str, str | None, str], World | Exception] = {}
    for job, report in zip(jobs, reports):
        metrics, video = job.out_dir / 'metrics.json', job.out_dir / VIDEO_NAME
        if not metrics.is_file() or (video.is_file()
                                     and video.stat().st_mtime >= metrics.stat().st_mtime):
            continue
        scenario = job.run.scenario
        key = (scenario.world, scenario.robot, repr(scenario.start))
        if key not in worlds:
            try:  # the robot where the run started it: a 'mirrored' start is turned round
                worlds[key] = started_world(World.load(scenario.world, robot=scenario.robot),
                                            scenario.start)
            except (WorldError, OSError, RunError) as error:
                worlds[key] = error
        banner = names if names is not None else job.label.partition('/')[0] if job.label else ''
        try:
            if not isinstance(worlds[key], World):
                raise VideoError(f'world: {worlds[key]}')
            if report.sim_time_s <= 0:
                raise VideoError('the run simulated nothing')
            render_video(job.out_dir, video, banner, teleop=bool(scenario.drive),
                         world=worlds[key],
                         duration_s=min(report.sim_time_s, scenario.duration_s))
        except (VideoError, OSError) as error:
            note(f'no video of {job.name}: {error}')


def write_reports(args: argparse.Namespace, batch: grade_class.ClassBatch | None,
                  reports: list[RunReport], names: PathNames,
                  scenarios: list[Scenario] | None = None, notes: Sequence[str] = ()) -> int:
    """
    Write and print a finished batch's reports; return the grader's exit status.

    ``notes`` come first in every report (how the runs were isolated, when not fully).
    The status is 0 when every run passed, 1 when any run failed, whatever made it fail (its
    criteria, a node that raised, a file not submitted or too big to read, a run that could
    not start), or an output could not be written: a class's runs of missing files count as
    the runs of the files found do.
    """
    graded = reports + [report for _, report in batch.missing] if batch is not None else reports
    status = 0 if all(report.passed for report in graded) else 1
    if batch is not None:
        text, unwritten = batch.write_outputs(reports, names, notes)
        print_out(text)
        return status if not unwritten else max(status, 1)
    notes = [*notes, *reuse_notes(reports, args.out)]
    scenarios = scenarios or []
    tasks = marks.task_marks(scenarios, [report.as_dict(names) for report in reports])
    # The files first: a console that has gone (`| head`) must not cost the report.
    writers = {
        args.out / REPORT_NAME: lambda path: write_report(
            reports, path, overrides=args.node_override, names=names, notes=notes,
            marks=tasks),
        args.out / PAGE_NAME: lambda path: html_report.write_runs_page(
            path, 'Grading report', [report.as_dict(names) for report in reports],
            root=args.out, notes=notes, marks=tasks)}
    if getattr(args, 'gradescope', None) is not None:
        writers[args.gradescope] = lambda path: gradescope.write_results(
            path, gradescope.results(reports, scenarios, format_table, names, notes))
    unwritten = write_outputs(writers)
    lines = [format_table(reports, failures_only=args.quiet)] if not args.quiet or status else []
    lines.append(summary(reports, tasks))
    lines += [f'note: {note}' for note in notes]
    written = [printable(os.fspath(path)) for path in writers if path not in unwritten]
    if written:
        lines.append(f"report: {' and '.join([', '.join(written[:-1]), written[-1]][-2:])}"
                     if len(written) > 1 else f'report: {written[0]}')
    print_out('\n'.join(lines))
    return max(status, 1) if unwritten else status


def print_out(text: str) -> None:
    """Print ``text`` on stdout; a pipe whose reader has exited (``| head``) takes no more."""
    try:
        print(text, flush=True)
    except BrokenPipeError:
        # As Python's documentation advises: stdout to devnull, so the flush at exit is quiet.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


if __name__ == '__main__':
    sys.exit(main())

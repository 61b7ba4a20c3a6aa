"""``dhlog batch``: many logs in worker processes into one summary table."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, NoReturn

import typer

from dhlog.cli.common import (
    EXIT_IMPLAUSIBLE,
    EXIT_INTERRUPTED,
    EXIT_PARTIAL,
    EXIT_TERMINATED,
    EXIT_USAGE,
    Ended,
    Terminated,
    check_writable,
    fail,
    plain,
    stderr,
    stdout,
)
from dhlog.cli.options import load_pipeline, model_request
from dhlog.errors import DhlogError, OutputError


def batch(
    logs: Annotated[
        list[Path], typer.Argument(metavar="LOG", help="Session logs (.mcap, bag folders).")
    ],
    out: Annotated[
        Path,
        typer.Option(metavar="DIR", help="Folder for every log's results and the summary."),
    ],
    jobs: Annotated[
        int,
        typer.Option(
            "--jobs",
            "-j",
            metavar="N",
            help="Logs processed at once (worker processes; with --scheduler, the cluster's "
            "workers).",
        ),
    ] = 1,
    pipeline: Annotated[
        str | None,
        typer.Option(
            metavar="NAME|FILE",
            help="A shipped pipeline's name (dhlog pipelines lists them) or a pipeline file, for "
            "every log (default: chosen per log from its topics).",
        ),
    ] = None,
    nominal: Annotated[
        str | None,
        typer.Option(
            metavar="ROBOT|FILE", help="A nominal DH file (or library robot), for every log."
        ),
    ] = None,
    no_rrd: Annotated[
        bool, typer.Option("--no-rrd", help="Do not write the Rerun recordings.")
    ] = False,
    analytic_only: Annotated[
        bool,
        typer.Option(
            "--analytic-only",
            help="Only the per-joint circle fits and line geometry, for every log.",
        ),
    ] = False,
    units: Annotated[
        str, typer.Option(metavar="mm|m", help="Units of each log's CSV: mm or m.")
    ] = "mm",
    holdout: Annotated[
        int,
        typer.Option(
            metavar="K",
            help="K-fold cross-validation of every log (K ≥ 2; 0: none): held-out errors "
            "before and after in each result and in the summary.",
        ),
    ] = 0,
    model: Annotated[
        str,
        typer.Option(
            metavar="auto|geometric|compliance|harmonic|full",
            help="Terms beyond the geometry, as dhlog process --model.",
        ),
    ] = "auto",
    force: Annotated[bool, typer.Option("--force", help="Overwrite existing results.")] = False,
    executor: Annotated[
        str,
        typer.Option(
            metavar="process|dask",
            help="Where the logs are processed: process, a pool of --jobs worker processes; "
            "dask, a Dask cluster (pip install 'dhlog[dask]'): the one at --scheduler, or one "
            "started here with --jobs workers.",
        ),
    ] = "process",
    scheduler: Annotated[
        str | None,
        typer.Option(
            metavar="ADDRESS",
            help="The Dask scheduler's address (tcp://host:8786), with --executor dask; its "
            "workers must see the logs and --out at the same paths (a shared file system).",
        ),
    ] = None,
) -> None:
    """Process many logs in --jobs workers into one summary table (a failing log is a row)."""
    import time

    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from dhlog.fleet.batch import (
        HOLDOUT_SUFFIX,
        TERMS_SUFFIX,
        BatchJob,
        check_paths,
        output_stamps,
        run_batch,
        stem_of,
        summary_frame,
        summary_paths,
        write_summary,
        written_logs,
    )
    from dhlog.fleet.executors import EXECUTORS
    from dhlog.identify.model.select import MODELS

    if jobs < 1 or jobs > 256:
        stderr.print(f"error: --jobs must be between 1 and 256, not {jobs}.")
        raise typer.Exit(EXIT_USAGE)
    if executor not in EXECUTORS:
        stderr.print(
            f"error: --executor must be one of {', '.join(EXECUTORS)}, not '{plain(executor)}'."
        )
        raise typer.Exit(EXIT_USAGE)
    if scheduler is not None and executor != "dask":
        stderr.print("error: --scheduler is the address of a Dask scheduler: add --executor dask.")
        raise typer.Exit(EXIT_USAGE)
    if units not in ("mm", "m"):
        stderr.print(f"error: --units must be mm or m, not '{plain(units)}'.")
        raise typer.Exit(EXIT_USAGE)
    if model not in MODELS:  # said here: the value is the user's text, never markup
        stderr.print(f"error: --model must be one of {', '.join(MODELS)}, not '{plain(model)}'.")
        raise typer.Exit(EXIT_USAGE)
    if holdout == 1 or not 0 <= holdout <= 1000:
        stderr.print(f"error: --holdout must be 0 (none) or a fold count of 2-1000, not {holdout}.")
        raise typer.Exit(EXIT_USAGE)
    stems: dict[str, Path] = {}
    for log in logs:
        other = stems.setdefault(stem_of(log), log)
        if other != log:
            stderr.print(
                f"error: {plain(other)} and {plain(log)} would write the same "
                "results; rename one, or process them into different folders."
            )
            raise typer.Exit(EXIT_USAGE)
    work = [
        BatchJob(
            str(log), str(out), pipeline, nominal, no_rrd, analytic_only, units, holdout, model
        )
        for log in logs
    ]
    try:  # exit 2, with or without --force: no input is overwritten, no output is a folder
        check_paths(work, out)
    except DhlogError as exc:
        fail(exc)
    suffixes = [".dh.json", ".dh.csv", *([] if no_rrd else [".rrd"])]
    suffixes += [HOLDOUT_SUFFIX] if holdout else []
    request = model_request(model, None, None)
    suffixes += [TERMS_SUFFIX] if request.mode != "geometric" and not analytic_only else []
    wanted = [out / f"{s}{x}" for s in stems for x in suffixes] + summary_paths(out)
    clash = [str(p) for p in wanted if p.exists()]
    if clash and not force:
        stderr.print(f"error: {plain(clash[0])} (and {len(clash) - 1} more) exist; pass --force.")
        raise typer.Exit(EXIT_USAGE)
    check_writable(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        fail(OutputError(out, exc))
    if pipeline is not None:  # a misspelt name fails here, not once per log
        try:
            load_pipeline(pipeline)
        except DhlogError as exc:
            fail(exc)
    before = output_stamps(work)
    try:
        with Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=stderr,
            disable=not stderr.is_terminal,
        ) as bar:
            task = bar.add_task("logs", total=len(work))

            def done(row: dict[str, object]) -> None:
                bar.advance(task)
                if row["status"] != "ok":
                    bar.console.print(
                        f"{plain(row['log'])}: {row['status']}: {plain(row['reason'])}"
                    )

            start = time.perf_counter()
            try:
                rows = run_batch(work, jobs, done, executor=executor, scheduler=scheduler)
            except DhlogError as exc:
                fail(exc)
            seconds = time.perf_counter() - start
        frame = summary_frame(rows)
        try:
            paths = write_summary(frame, out, hold_signals=True)
        except OSError as exc:
            fail(OutputError(out, exc))
    except (KeyboardInterrupt, Terminated) as exc:  # the workers are stopped already
        _batch_stopped(exc, written_logs(work, before), len(work))
    counts = {
        s: sum(1 for r in rows if r["status"] == s)
        for s in ("ok", "partial", "implausible", "failed")
    }
    stdout.print(
        f"{len(rows)} log(s) in {seconds:.1f} s {_where(executor, scheduler, jobs)}: "
        f"{counts['ok']} ok, {counts['partial']} partial, "
        + (f"{counts['implausible']} implausible, " if counts["implausible"] else "")
        + f"{counts['failed']} failed; wrote "
        + ", ".join(plain(p) for p in paths)
    )
    if counts["partial"] or counts["failed"]:  # results missing: 3, whatever else
        raise typer.Exit(EXIT_PARTIAL)
    if counts["implausible"]:  # all written, some judged implausible
        raise typer.Exit(EXIT_IMPLAUSIBLE)


def _where(executor: str, scheduler: str | None, jobs: int) -> str:
    """Where the logs were processed, as the closing line says it."""
    if executor == "process":
        return f"with {jobs} worker(s)"
    if scheduler is None:
        return f"on a Dask cluster of {jobs} worker(s)"
    return f"on the Dask cluster at {plain(scheduler)}"


def _batch_stopped(cause: BaseException, written: list[str], total: int) -> NoReturn:
    """One line saying which logs' results an interrupted batch wrote (they are complete: each
    log's results are moved into place together), then exit 130 / 143."""

    code, what = (
        (EXIT_INTERRUPTED, "interrupted")
        if isinstance(cause, KeyboardInterrupt)
        else (EXIT_TERMINATED, "terminated")
    )
    if not written:
        stderr.print(
            f"{what}: no log had finished: nothing was written (no results, no summary; files "
            "of earlier runs stay as they were)."
        )
    else:
        names = [Path(log).name for log in written]
        shown = ", ".join(names[:6]) + (f" and {len(names) - 6} more" if len(names) > 6 else "")
        rest = "the summary was not" if len(written) == total else "the others' and the summary not"
        stderr.print(
            f"{what}: the results of {len(written)} of {total} log(s) were written "
            f"({plain(shown)}); {rest}."
        )
    raise Ended(code)

"""The command line's edges, tried as a new user would (issue 20): an interrupted batch, an
output folder that is a file, a misspelt pipeline, the help texts, a log cut short, a closed
standard output, narrow terminals and the README's commands. Interrupts are real signals sent
to a real ``dhlog`` (to its whole process group, as a terminal's Ctrl-C is)."""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

from dhlog.cli.app import app
from dhlog.cli.results import print_values

ROOT = Path(__file__).parents[1]
SAMPLE = ROOT / "sample_logs" / "kr5_0.01mm.mcap"
DHLOG = str(Path(sys.executable).with_name("dhlog"))
SHIPPED = ("ros2_tracker", "foxglove_json", "foxglove_protobuf", "phase_markers")
runner = CliRunner()


def _dhlog(*args: str, **kw: object) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "COLUMNS": "120"}
    return subprocess.run(  # type: ignore[call-overload,no-any-return]
        [DHLOG, *args], capture_output=True, text=True, env=env, **kw
    )


def _lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


# ---------------------------------------------------------------------------- help texts


def _flags(command: list[str]) -> list[str]:
    """The shown boolean flags of ``dhlog`` or one of its commands, ``--help`` among them."""
    from typer.main import get_command

    cmd = get_command(app)
    if command:
        cmd = cmd.commands[command[0]]  # type: ignore[attr-defined]
    shown = [p for p in cmd.params if getattr(p, "is_flag", False) and not p.hidden]
    return [*(p.opts[0] for p in shown), "--help"]


@pytest.mark.parametrize(
    "command", [[], ["process"], ["batch"], ["simulate"], ["compare"], ["import"], ["export"]]
)
def test_the_help_shows_flags_as_flags_and_values_by_name(command: list[str]) -> None:
    """typer 0.2x's rich help gave every flag a type (``--force <bool>``), arguments braces
    (``{log}``) and repeated options a Python type (``<list[Path]>``)."""
    done = _dhlog(*command, "--help")
    assert done.returncode == 0, done.stderr
    text = done.stdout
    for wrong in ("<bool>", "<list", "<path>", "<str>", "<int>", "<float>", "{", "BOOL"):
        assert wrong not in text, (wrong, text)
    flags = _flags(command)
    assert "--help" in flags and len(flags) >= 1
    for flag in flags:  # its help follows it directly: no value is asked for
        assert re.search(rf"{flag}\s+[A-Z][^A-Z|]", text), (flag, text)
    usage = next(line for line in text.splitlines() if "Usage:" in line)
    assert "{" not in usage and "<" not in usage
    assert "seed 00" not in text and "seed method" not in text


def test_usage_names_the_arguments_and_the_exit_codes_are_listed() -> None:
    process = _dhlog("process", "--help").stdout
    assert "Usage: dhlog process [OPTIONS] LOG" in process
    assert re.search(r"--pipeline\s+NAME\|FILE", process)
    assert re.search(r"--validate\s+LOG", process) and re.search(r"--out\s+DIR", process)
    assert re.search(r"--force\s+Overwrite", process) and re.search(r"--no-rrd\s+Do not", process)
    assert "Usage: dhlog batch [OPTIONS] LOG..." in _dhlog("batch", "--help").stdout
    assert "Usage: dhlog compare [OPTIONS] FIRST [SECOND]" in _dhlog("compare", "--help").stdout
    for text in (process, _dhlog("--help").stdout):
        flat = " ".join(text.split())
        for code in ("0 success", "1 usage error", "2 unreadable", "3 partial", "130 interrupted"):
            assert code in flat, code
        assert "141 the standard output was closed" in flat and "143 terminated" in flat


def test_process_help_and_the_pipeline_list_agree_on_what_pipeline_takes() -> None:
    process = " ".join(_dhlog("process", "--help").stdout.split())
    listed = _dhlog("pipelines").stdout
    assert "shipped pipeline's name" in process and "or a pipeline file" in process
    assert "--pipeline NAME" in listed and "--pipeline FILE" in listed
    for name in SHIPPED:
        assert name in listed


# ------------------------------------------------------------------- misspelt pipelines


def test_a_misspelt_pipeline_lists_the_shipped_ones_and_the_nearest(tmp_path: Path) -> None:
    done = _dhlog("process", str(SAMPLE), "--pipeline", "ros2_trackr", "--out", str(tmp_path))
    assert done.returncode == 2 and len(_lines(done.stderr)) == 1, done.stderr
    assert "did you mean 'ros2_tracker'?" in done.stderr
    assert "No such file" not in done.stderr and "cannot be read" not in done.stderr
    for name in SHIPPED:
        assert name in done.stderr
    assert not list(tmp_path.iterdir())
    missing = _dhlog("process", str(SAMPLE), "--pipeline", "cell.toml", "--out", str(tmp_path))
    assert missing.returncode == 2 and "no such pipeline file" in missing.stderr
    assert "ros2_tracker" in missing.stderr
    # a batch refuses it before any log is processed
    batch = _dhlog("batch", str(SAMPLE), "--out", str(tmp_path / "b"), "--pipeline", "foxglove")
    assert batch.returncode == 2 and "did you mean 'foxglove_json'?" in batch.stderr
    assert len(_lines(batch.stderr)) == 1 and not list((tmp_path / "b").iterdir())


# ----------------------------------------------------------------- an --out that is a file


@pytest.mark.parametrize(
    "args",
    [
        ["process", str(SAMPLE), "--out", "{file}", "--no-rrd"],
        ["process", str(SAMPLE), "--out", "{file}/sub", "--no-rrd"],
        ["batch", str(SAMPLE), "--out", "{file}", "--no-rrd"],
        ["simulate", "scara", "-o", "{file}/x.mcap"],
    ],
)
def test_an_output_folder_that_is_a_file_is_said_to_be_one(args: list[str], tmp_path: Path) -> None:
    """It was ``cannot write the results in afile (Permission denied)``."""
    a_file = tmp_path / "afile"
    a_file.write_text("mine\n")
    done = _dhlog(*(a.format(file=a_file) for a in args))
    assert done.returncode == 2, done.stderr
    (line,) = _lines(done.stderr)
    assert f"{a_file} is a file, not a folder" in line and "Permission denied" not in line
    assert a_file.read_text() == "mine\n" and sorted(tmp_path.iterdir()) == [a_file]


# ------------------------------------------------------- user text: printed as text, one line


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (
            ["process", str(SAMPLE), "--model", "[/]"],
            "--model must be one of auto, geometric, compliance, harmonic, full, not '[/]'.",
        ),
        (
            ["process", str(SAMPLE), "--units", "[bold]x[/]"],
            "--units must be mm or m, not '[bold]x[/]'.",
        ),
        (
            ["process", str(SAMPLE), "--gravity", "[/]"],
            "--gravity must be finite numbers separated by commas, not '[/]'.",
        ),
        (
            ["simulate", "scara", "-o", "{d}/s.mcap", "--encoding", "[/]"],
            "--encoding must be one of ros2, json, protobuf, not '[/]'.",
        ),
        (
            ["simulate", "scara", "-o", "{d}/s.mcap", "--compliance", "[/]"],
            "--compliance takes J:C groups separated by ',', not '[/]'.",
        ),
        (["fk", "kr5", "--q", "0", "--units", "[/]"], "--units must be mm or m, not '[/]'."),
        (["fk", "kr5", "--q", "0", "--units", ":a:"], "--units must be mm or m, not ':a:'."),
        (
            [
                "plan",
                "kr5",
                "--candidates",
                "{d}/c.csv",
                "--select",
                "2",
                "-o",
                "{d}/o.csv",
                "--angle-unit",
                "[/]",
            ],
            "--angle-unit must be rad or deg, not '[/]'.",
        ),
    ],
)
def test_markup_in_an_option_value_is_printed_as_text(
    args: list[str], said: str, tmp_path: Path
) -> None:
    """``--model '[/]'`` ended in rich's MarkupError (a traceback): an option's value is the
    user's text, never markup (nor an emoji code: ``:a:`` was 🅰)."""
    done = runner.invoke(app, [a.format(d=tmp_path) for a in args])
    assert done.exit_code == 1 and isinstance(done.exception, SystemExit), done.output
    assert _lines(done.stderr) == [f"error: {said}"]
    assert not list(tmp_path.iterdir())


def test_an_unknown_option_holding_markup_is_a_usage_error() -> None:
    """The parser's own message quotes the option: it was a MarkupError traceback too."""
    done = _dhlog("process", "--[/]x")
    assert done.returncode == 1, done.stderr
    assert _lines(done.stderr) == ["error: No such option: --[/]x (see dhlog --help)"]


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (
            ["simulate", "scara", "-o", "{d}/s.mcap", "--compliance", "inf:1e-8"],
            "--compliance takes J:C groups separated by ',', not 'inf:1e-8'.",
        ),
        (
            ["simulate", "scara", "-o", "{d}/s.mcap", "--harmonic", "nan:1e-4:0"],
            "--harmonic takes J:A:B groups separated by ',', not 'nan:1e-4:0'.",
        ),
        (
            ["simulate", "scara", "-o", "{d}/s.mcap", "--skip-joints", "inf"],
            "--skip-joints takes joint numbers (1, 2, …), not 'inf'.",
        ),
        (
            ["simulate", "scara", "-o", "{d}/s.mcap", "--skip-joints", "1.5"],
            "--skip-joints takes joint numbers (1, 2, …), not '1.5'.",
        ),
        (
            ["process", str(SAMPLE), "--harmonic-joints", "inf"],
            "--harmonic-joints takes joint numbers (1, 2, …), not 'inf'.",
        ),
        (
            ["fk", "kr5", "--q", "0,0,nan,0,0,0"],
            "--q must be finite numbers separated by commas, not '0,0,nan,0,0,0'.",
        ),
        (
            ["process", str(SAMPLE), "--reference-pose", "inf,0,0,0,0,0"],
            "--reference-pose must be finite numbers separated by commas, not 'inf,0,0,0,0,0'.",
        ),
    ],
)
def test_a_joint_number_that_is_not_whole_is_refused_by_name(
    args: list[str], said: str, tmp_path: Path
) -> None:
    """``inf`` or ``nan`` as a joint number ended in OverflowError / ValueError tracebacks;
    ``--skip-joints 1.5`` skipped joint 1."""
    done = runner.invoke(app, [a.format(d=tmp_path) for a in args])
    assert done.exit_code == 1 and isinstance(done.exception, SystemExit), done.output
    assert _lines(done.stderr) == [f"error: {said}"]
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("args", "code", "existing"),
    [
        (["process", "{odd}.mcap", "--no-rrd"], 2, None),  # the log cannot be read
        (["process", str(SAMPLE), "--masses", "{odd}.urdf"], 1, None),  # no such file
        (["show", "kr5", "-o", "{odd}.rrd"], 1, "{odd}.rrd"),  # exists, no --force
        (["simulate", "scara", "-o", "{odd}/s.mcap"], 1, None),  # the folder does not exist
        (["simulate", "scara", "-o", "{odd}/s.mcap"], 2, "{odd}"),  # the folder is a file
    ],
)
def test_a_path_holding_a_line_break_is_shown_on_one_line(
    args: list[str], code: int, existing: str | None, tmp_path: Path
) -> None:
    """An error is one line: a newline in a path is shown escaped, ``\\x0a``."""
    odd = str(tmp_path / "a\nb")
    if existing is not None:
        Path(existing.format(odd=odd)).write_text("mine\n")
    before = sorted(tmp_path.iterdir())
    done = runner.invoke(app, [a.format(odd=odd) for a in args])
    assert done.exit_code == code, done.output
    (line,) = _lines(done.stderr)
    assert line.startswith("error: ") and str(tmp_path / "a\\x0ab") in line, line
    assert sorted(tmp_path.iterdir()) == before


# ------------------------------------------------------------------- compare's recording


@pytest.fixture(scope="module")
def summary(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A batch summary (CSV) of real rows."""
    from fuzz_results import make_bases, summary_bytes

    folder = tmp_path_factory.mktemp("summary")
    path = folder / "summary.csv"
    path.write_bytes(summary_bytes(make_bases(folder / "bases").rows, "csv"))
    return path


def test_compare_keeps_an_existing_recording_without_force(summary: Path, tmp_path: Path) -> None:
    """``compare SUMMARY --rrd old.rrd`` wrote over the recording; like every other output it
    now needs --force, and is refused before any work."""
    rrd = tmp_path / "trend.rrd"
    rrd.write_bytes(b"mine")
    done = runner.invoke(app, ["compare", str(summary), "--rrd", str(rrd)])
    assert done.exit_code == 1, done.output
    assert _lines(done.stderr) == [f"error: {rrd} exists; pass --force to overwrite it."]
    assert done.stdout == "" and rrd.read_bytes() == b"mine"
    assert sorted(tmp_path.iterdir()) == [rrd]
    forced = runner.invoke(app, ["compare", str(summary), "--rrd", str(rrd), "--force"])
    assert forced.exit_code == 0, forced.output
    assert rrd.read_bytes() != b"mine" and rrd.stat().st_size > 0


# ------------------------------------------------------------------------ damaged logs


def test_a_log_cut_short_is_said_to_be_cut_short_not_unmatched(tmp_path: Path) -> None:
    from dhlog.io.mcapscan import scan_mcap

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(SAMPLE.read_bytes()[:50_000])  # inside the first chunk: no channel left
    at = scan_mcap(cut).truncated_at
    done = _dhlog("process", str(cut), "--no-rrd", "--out", str(tmp_path / "out"))
    assert done.returncode == 2, done.stderr
    (line,) = _lines(done.stderr)
    assert f"cut short (or damaged) at byte {at} of 50000" in line
    assert "no channel could be recovered" in line and "no shipped pipeline" not in line
    # channels recovered, the pipeline's topic not among them: the damage is named too
    later = tmp_path / "later.mcap"
    later.write_bytes(SAMPLE.read_bytes()[:150_000])
    named = _dhlog("process", str(later), "--pipeline", "phase_markers", "--no-rrd")
    (line,) = _lines(named.stderr)
    assert named.returncode == 2 and "cut short (or damaged) at byte" in line
    assert "/tracker/point" in line and "which the pipeline phase_markers needs" in line
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- a closed standard output


def _closed_pipe() -> int:
    """The write end of a pipe whose reader is gone (``| head -1`` after its line)."""
    read, write = os.pipe()
    os.close(read)
    return write


@pytest.mark.parametrize("args", [["--help"], ["pipelines"], ["fk", "kr5", "--q", "0,0,0,0,0,0"]])
def test_a_closed_output_ends_quietly_with_141(args: list[str]) -> None:
    write = _closed_pipe()
    try:
        done = subprocess.run([DHLOG, *args], stdout=write, stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write)
    assert done.returncode == 141 and done.stderr == "", done.stderr


def test_process_into_a_closed_output_has_written_its_results(tmp_path: Path) -> None:
    write = _closed_pipe()
    try:
        done = subprocess.run(
            [DHLOG, "process", str(SAMPLE), "--no-rrd", "--out", str(tmp_path)],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
        )
    finally:
        os.close(write)
    assert done.returncode == 141 and done.stderr == "", done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "kr5_0.01mm.dh.csv",
        "kr5_0.01mm.dh.json",
        "kr5_0.01mm.terms.csv",
    ]


def test_head_reads_its_line_and_the_pipeline_ends_cleanly(tmp_path: Path) -> None:
    """The shell's own ``dhlog process … | head -1`` (with pipefail: dhlog's status)."""
    script = f"set -o pipefail; {DHLOG} process {SAMPLE} --no-rrd --out {tmp_path} | head -1"
    done = subprocess.run(["bash", "-c", script], capture_output=True, text=True)
    assert done.returncode in (0, 141), done.stderr  # 0: everything fitted in the pipe first
    assert len(_lines(done.stdout)) == 1 and done.stderr == ""


# ----------------------------------------------------------------------- narrow terminals

ROWS = [
    ("theta_offset_3", "0.0005", "0.0004", "+0.0001 °", "0.0011", "0.1"),
    ("a_2", "599.9996", "600.4986", "+0.4990 mm", "0.0015", "330.2 *"),
    ("tool_z", "100.0028", "-1300.0031", "+0.0003 mm", "fixed", ""),
    ("base_z_long_parameter_name", "-419.9988", "-419.9990", "-0.0002 mm", "0.0011", "0.2"),
]
HEADS = ("A", "B", "B − A", "σ", "|B − A|\n/ σ")


@pytest.mark.parametrize("width", [100, 72, 60, 40, 24])
def test_compare_tables_never_cut_a_value(width: int) -> None:
    """On a narrow terminal rich squeezed every column and cut values (and whole narrow
    columns) without a sign; every value now appears whole, within the width."""
    console = Console(width=width, record=True, file=open(os.devnull, "w"))
    print_values(console, "Changes (B − A; σ: both sessions combined)", HEADS, ROWS)
    text = console.export_text()
    assert all(len(line) <= width for line in text.splitlines())
    assert "…" not in text
    joined = " ".join(text.split())
    for row in ROWS:
        for value in row[1:]:
            assert value in joined, (value, text)
    if width >= 72:  # room for the table: a header rule, one row a line
        assert "────" in text and sum("599.9996" in line for line in text.splitlines()) == 1


def test_compare_of_two_results_on_a_60_column_terminal(tmp_path: Path) -> None:
    outs = []
    for k, dh in enumerate(("kr5", "kr5")):
        log = tmp_path / f"s{k}.mcap"
        made = runner.invoke(app, ["simulate", dh, "-o", str(log), "--seed", str(k)])
        assert made.exit_code == 0, made.output
        done = runner.invoke(app, ["process", str(log), "--no-rrd", "--out", str(tmp_path)])
        assert done.exit_code == 0, done.output
        outs.append(str(tmp_path / f"s{k}.dh.json"))
    done = subprocess.run(
        [DHLOG, "compare", *outs],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "60"},
    )
    assert done.returncode == 0, done.stderr
    assert all(len(line) <= 60 for line in done.stdout.splitlines())
    assert "…" not in done.stdout and re.search(
        r"a_2\b.*A -?\d+\.\d{4}", " ".join(done.stdout.split())
    )


# ------------------------------------------------------------------- the docs' walkthroughs

#: docs/ pages that are not a job's walkthrough (the set-up commands, the figures' benchmarks)
NOT_WALKTHROUGHS = {"index", "getting-started", "accuracy", "performance", "robustness"}


def test_the_readme_walkthroughs_run_dhlog_from_the_venv() -> None:
    """The set-up installs into .venv without touching PATH: a bare ``dhlog`` in a walkthrough
    (the job pages of docs/, where the README's walkthroughs moved) is ``command not found``."""
    pages = [p for p in sorted((ROOT / "docs").glob("*.md")) if p.stem not in NOT_WALKTHROUGHS]
    after_setup = "\n".join(p.read_text() for p in pages)
    text = (ROOT / "docs" / "getting-started.md").read_text() + after_setup
    blocks = re.findall(r"```sh\n(.*?)```", after_setup, re.S)
    assert len(blocks) >= 2
    for block in blocks:
        for line in _lines(block):
            assert line.split()[0] == ".venv/bin/dhlog", line
    for inline in re.findall(r"`((?:\S*/)?dhlog (?:import|process|export) [^`]*)`", after_setup):
        if "/" in inline.split()[0] or inline.startswith("dhlog process run.mcap ["):
            continue
        assert "<" not in inline  # command names in prose, not commands to type
    assert ". .venv/bin/activate" in text
    assert re.search(r"`\.venv/bin/dhlog import points\.txt", text)


# ---------------------------------------------------------------------- interrupted batch


def _group(pgid: int) -> list[str]:
    """The command lines of the live processes of a process group (zombies aside)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            if int(stat.rsplit(")", 1)[1].split()[2]) != pgid or ") Z " in stat:
                continue
            found.append((entry / "cmdline").read_bytes().replace(b"\0", b" ").decode())
        except (OSError, ValueError, IndexError):
            continue
    return found


def _gone(pgid: int, within: float) -> bool:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        if not _group(pgid):
            return True
        time.sleep(0.05)
    return False


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """A quick log (a SCARA) and two slow ones (KR5 at 1 kHz: with --holdout 100 each takes
    20 s or more), in that order: with two workers the quick one finishes while the slow
    ones run."""
    folder = tmp_path_factory.mktemp("interrupt")
    made = [
        ("quick", "scara", ["--sweep-deg", "30"]),
        ("slow_a", "kr5", ["--tracker-rate", "1000"]),
    ]
    made.append(("slow_b", "kr5", ["--tracker-rate", "1000", "--seed", "4"]))
    out = []
    for stem, robot, extra in made:
        log = folder / f"{stem}.mcap"
        done = runner.invoke(app, ["simulate", robot, "-o", str(log), *extra])
        assert done.exit_code == 0, done.output
        out.append(log)
    return out


@pytest.fixture
def batches() -> Iterator[list[subprocess.Popen[str]]]:
    """The batches a test starts, each killed with its workers if the test left it running."""
    started: list[subprocess.Popen[str]] = []
    yield started
    for proc in started:
        if proc.poll() is None or _group(proc.pid):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()


def _batch(
    logs: list[Path], out: Path, started: list[subprocess.Popen[str]]
) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [DHLOG, "batch", *map(str, logs), "--out", str(out), "-j", "2", "--holdout", "100"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group: the terminal's Ctrl-C is sent to it
    )
    started.append(proc)
    return proc


def _written(out: Path) -> dict[str, list[str]]:
    files: dict[str, list[str]] = {}
    for p in sorted(out.iterdir()) if out.exists() else []:
        files.setdefault(p.name.split(".")[0], []).append(p.name)
    return files


def _complete(stem: str) -> list[str]:
    return sorted(
        f"{stem}{s}" for s in (".dh.csv", ".dh.json", ".holdout.csv", ".rrd", ".terms.csv")
    )


def test_ctrl_c_while_the_workers_start_stops_them_without_a_traceback(
    logs: list[Path], tmp_path: Path, batches: list[subprocess.Popen[str]]
) -> None:
    """Ctrl-C reaches every process of the group; workers that were importing printed their
    tracebacks before the clean line."""
    out = tmp_path / "out"
    proc = _batch(logs, out, batches)
    deadline = time.monotonic() + 60
    while sum("spawn_main" in c for c in _group(proc.pid)) < 2:
        assert time.monotonic() < deadline and proc.poll() is None
        time.sleep(0.01)
    sent = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert time.monotonic() - sent < 8.0
    assert proc.returncode == 130, err
    assert "Traceback" not in err and len(_lines(err)) == 1, err
    assert "nothing was written" in err
    assert _written(out) == {}
    assert _gone(proc.pid, 5.0), _group(proc.pid)


@pytest.mark.parametrize(
    ("signum", "code", "to_group"), [(signal.SIGINT, 130, True), (signal.SIGTERM, 143, False)]
)
def test_an_interrupted_batch_stops_its_workers_and_says_what_it_wrote(
    signum: int,
    code: int,
    to_group: bool,
    logs: list[Path],
    tmp_path: Path,
    batches: list[subprocess.Popen[str]],
) -> None:
    """Before: the running workers went on for up to 25 s, wrote their results, and the
    command then said ``interrupted: no output was written``. Now the workers stop at once, the
    line names the logs whose results were written (complete), nothing else is there."""
    out = tmp_path / "out"
    proc = _batch(logs, out, batches)
    deadline = time.monotonic() + 120
    while not (out / "quick.dh.json").exists():
        assert time.monotonic() < deadline and proc.poll() is None, proc.stderr
        time.sleep(0.02)
    time.sleep(0.5)  # the slow logs are well under way
    sent = time.monotonic()
    if to_group:
        os.killpg(proc.pid, signum)
    else:
        proc.send_signal(signum)
    _, err = proc.communicate(timeout=30)
    assert time.monotonic() - sent < 8.0  # the slow logs had 15 s or more to go
    assert proc.returncode == code, err
    assert "Traceback" not in err and len(_lines(err)) == 1, err
    assert "the results of 1 of 3 log(s) were written (quick.mcap)" in err
    assert _written(out) == {"quick": _complete("quick")}  # no .part, no summary, no slow log
    assert _gone(proc.pid, 5.0), _group(proc.pid)

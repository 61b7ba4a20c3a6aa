"""The long fuzz runs: many hostile inputs through the real commands, each in its own process.

    .venv/bin/python benchmarks/fuzz.py [--kind logs|inputs|results|images] [--cases 10000]
                                        [--workers 2] [--seed 0] [--timeout 60]
                                        [--out fuzz-failures]

``--kind logs`` (the default): ``tests/fuzzing.py``'s damaged logs (four families in turn:
bytes, records, payloads, odd) through ``dhlog process LOG --no-rrd --out DIR``.
``--kind inputs``: ``tests/fuzz_inputs.py``'s DH files, pipelines and tracker exports (``fk``,
``process --nominal``, ``process --pipeline``, ``import``). ``--kind results``:
``tests/fuzz_results.py``'s result JSONs, batch summaries, URDF templates, names and output
paths (``compare``, ``export``, ``batch``). ``--kind images``: ``tests/fuzz_images.py``'s
damaged vision logs (bytes, records, payloads, and image messages rewritten field by field),
each read frame by frame by ``ImageStream`` and ``detect`` and then run through ``dhlog
process`` (exit 2, one line).

Each case runs in a child forked from a warm parent (dhlog imported once, the real inputs the
cases start from made once), with a time limit; the child's peak RSS comes from ``wait4``.
Printed: cases, outcomes (exit codes) and problems per family, the slowest and the largest
cases, and one reproducer per distinct problem (``--out``: the case pickled, and its name,
problems and stderr).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import pickle
import shutil
import signal
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from typing import Any

import fuzzing


@dataclass(frozen=True)
class Harness:
    """One kind of fuzz case: its families, its seeded cases, and how a child runs one."""

    families: tuple[str, ...]
    cases: Iterator[Any]
    run: Callable[[Any, Path], Any]


def harness(kind: str, count: int, seed: int, work: Path) -> Harness:
    """The cases of ``kind`` (their real inputs made once, here, in the parent)."""
    if kind == "logs":
        return Harness(
            fuzzing.FAMILIES, fuzzing.cases(count, seed, work / "base"), fuzzing.run_in_process
        )
    if kind == "images":
        import fuzz_images

        return Harness(
            fuzz_images.FAMILIES,
            from_child(
                lambda: fuzz_images.cases(count, seed, fuzz_images.make_base(work / "base"))
            ),
            lambda case, folder: fuzz_images.run_case(case, folder, timeout=1e9),
        )
    import fuzz_inputs
    import fuzz_results

    module: Any = fuzz_inputs if kind == "inputs" else fuzz_results
    (work / "base").mkdir()
    return Harness(
        module.FAMILIES,
        from_child(lambda: module.cases(seed, count, module.make_bases(work / "base"))),
        lambda case, folder: module.run_case(case, folder, timeout=1e9),
    )


def from_child(make: Callable[[], Iterator[Any]]) -> Iterator[Any]:
    """The cases ``make()`` yields — the real inputs they start from made first — in a forked
    child, pickled back one by one: the parent never runs a polars query (the summaries' cases
    write Parquet), since a child forked after polars ran one can wait on its threads forever."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        code = 1
        try:
            os.close(r)
            with os.fdopen(w, "wb") as f:
                for case in make():
                    blob = pickle.dumps(case)
                    f.write(len(blob).to_bytes(8, "little") + blob)
            code = 0
        finally:
            os._exit(code)  # never back into the parent's main()
    os.close(w)
    with os.fdopen(r, "rb") as f:
        while size := f.read(8):
            want = int.from_bytes(size, "little")
            blob = f.read(want)
            if len(size) < 8 or len(blob) < want:
                break  # the generator died mid-case
            yield pickle.loads(blob)
    _, status = os.waitpid(pid, 0)
    if status:
        raise SystemExit("making the fuzz cases failed (their generator's child died)")


def start(run: Callable[[Any, Path], Any], case: Any, folder: Path) -> tuple[int, int]:
    """Fork a child that runs ``case`` and writes its pickled outcome to a pipe."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        os.close(r)
        try:
            outcome = run(case, folder)
        except BaseException as exc:  # the harness itself failed: report, never hang
            outcome = fuzzing.Outcome(case.name, case.family, -1, (f"harness: {exc!r}",), "")
        with os.fdopen(w, "wb") as f:
            f.write(pickle.dumps(outcome))
        os._exit(0)
    os.close(w)
    return pid, r


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--kind", choices=("logs", "inputs", "results", "images"), default="logs")
    parser.add_argument("--cases", type=int, default=10000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--out", type=Path, default=Path("fuzz-failures"))
    args = parser.parse_args()
    import dhlog.cli.app
    import dhlog.identify.run  # noqa: F401

    work = Path(tempfile.mkdtemp(prefix="dhlog-fuzz-"))
    chosen = harness(args.kind, args.cases, args.seed, work)
    generator = chosen.cases
    slots = [work / f"slot{k}" for k in range(args.workers)]
    for s in slots:
        s.mkdir()
    running: dict[int, tuple[Any, int, float, int]] = {}  # pid -> case, fd, start, slot
    free = list(range(args.workers))
    results: list[tuple[Any, float, float]] = []
    begun = time.time()
    exhausted = False
    reported = 0
    while running or not exhausted:
        while free and not exhausted:
            case = next(generator, None)
            if case is None:
                exhausted = True
                break
            slot = free.pop()
            pid, fd = start(chosen.run, case, slots[slot])
            running[pid] = (case, fd, time.time(), slot)
        time.sleep(0.005)
        for pid in list(running):
            case, fd, t0, slot = running[pid]
            done, status, usage = os.wait4(pid, os.WNOHANG)
            elapsed = time.time() - t0
            if done == 0 and elapsed < args.timeout:
                continue
            if done == 0:  # a hang: kill it
                os.kill(pid, signal.SIGKILL)
                _, status, usage = os.wait4(pid, 0)
                outcome = fuzzing.Outcome(case.name, case.family, -9, ("hang",), "")
            else:
                with os.fdopen(fd, "rb") as f:
                    blob = f.read()
                fd = -1
                outcome = (
                    pickle.loads(blob)
                    if blob
                    else fuzzing.Outcome(
                        case.name, case.family, -1, (f"child died ({status})",), ""
                    )
                )
            if fd >= 0:
                os.close(fd)
            rss = usage.ru_maxrss / 1024.0  # MiB (ru_maxrss is in KiB on Linux)
            if rss > 1024:
                outcome = replace(outcome, problems=(*outcome.problems, f"peak RSS {rss:.0f} MiB"))
            results.append((outcome, elapsed, rss))
            if outcome.problems:
                key = hashlib.sha256(
                    (",".join(outcome.problems) + outcome.stderr[-120:]).encode()
                ).hexdigest()[:12]
                args.out.mkdir(exist_ok=True)
                target = args.out / f"{key}.case.pickle"
                if not target.exists():
                    target.write_bytes(pickle.dumps(case))
                    (args.out / f"{key}.txt").write_text(
                        f"{outcome.case}\n{outcome.problems}\n{outcome.stderr}\n"
                    )
            del running[pid]
            free.append(slot)
        if len(results) >= reported + 500:
            reported = len(results) // 500 * 500
            print(f"... {len(results)} cases, {time.time() - begun:.0f} s", flush=True)
    total = time.time() - begun
    print(
        f"\n{len(results)} {args.kind} cases in {total:.0f} s "
        f"({args.workers} workers, seed {args.seed})\n"
    )
    print("| family | cases | exit 0 | exit 2 | exit 3 | problems |")
    print("|---|---|---|---|---|---|")
    for family in chosen.families:
        mine = [o for o, _, _ in results if o.family == family]
        codes = Counter(o.exit_code for o in mine)
        bad = sum(1 for o in mine if o.problems)
        print(
            f"| {family} | {len(mine)} | {codes.get(0, 0)} | {codes.get(2, 0)} | "
            f"{codes.get(3, 0)} | {bad} |"
        )
    kinds: dict[str, int] = defaultdict(int)
    for o, _, _ in results:
        for p in o.problems:
            kinds[p.split(" ")[0]] += 1
    print("\nproblems:", dict(kinds) or "none")
    slow = max(results, key=lambda r: r[1])
    big = max(results, key=lambda r: r[2])
    print(f"slowest: {slow[0].case} {slow[1]:.2f} s; largest: {big[0].case} {big[2]:.0f} MiB")
    print(f"reproducers: {args.out}/" if any(o.problems for o, _, _ in results) else "")
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()

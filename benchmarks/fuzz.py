"""The long fuzz run: many mutated logs through ``dhlog process``, each in its own process.

    .venv/bin/python benchmarks/fuzz.py [--cases 10000] [--workers 2] [--seed 0]
                                        [--timeout 60] [--out fuzz-failures]

The cases are ``tests/fuzzing.py``'s (four families in turn: bytes, records, payloads, odd).
Each runs ``dhlog process LOG --no-rrd --out DIR`` in a child forked from a warm parent (dhlog
imported once), with a time limit; the child's peak RSS comes from ``wait4``. Printed: cases,
outcomes (exit codes) and problems per family, the slowest and the largest cases, and one
reproducer file per distinct problem (``--out``: the log, and its name and stderr).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import pickle
import signal
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fuzzing import FAMILIES, Case, Outcome, cases, run_in_process


def start(case: Case, folder: Path) -> tuple[int, int]:
    """Fork a child that runs ``case`` and writes its pickled Outcome to a pipe."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child
        os.close(r)
        try:
            outcome = run_in_process(case, folder)
        except BaseException as exc:  # the harness itself failed: report, never hang
            outcome = Outcome(case.name, case.family, -1, (f"harness: {exc!r}",), "")
        with os.fdopen(w, "wb") as f:
            f.write(pickle.dumps(outcome))
        os._exit(0)
    os.close(w)
    return pid, r


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--cases", type=int, default=10000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=60.0)
    parser.add_argument("--out", type=Path, default=Path("fuzz-failures"))
    args = parser.parse_args()
    import dhlog.cli.app
    import dhlog.identify.run  # noqa: F401

    work = Path(tempfile.mkdtemp(prefix="dhlog-fuzz-"))
    generator = cases(args.cases, args.seed, work / "base")
    slots = [work / f"slot{k}" for k in range(args.workers)]
    for s in slots:
        s.mkdir()
    running: dict[int, tuple[Case, int, float, int]] = {}  # pid -> case, fd, start, slot
    free = list(range(args.workers))
    results: list[tuple[Outcome, float, float]] = []
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
            pid, fd = start(case, slots[slot])
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
                outcome = Outcome(case.name, case.family, -9, ("hang",), "")
            else:
                with os.fdopen(fd, "rb") as f:
                    blob = f.read()
                fd = -1
                outcome = (
                    pickle.loads(blob)
                    if blob
                    else Outcome(case.name, case.family, -1, (f"child died ({status})",), "")
                )
            if fd >= 0:
                os.close(fd)
            rss = usage.ru_maxrss / 1024.0  # MiB (ru_maxrss is in KiB on Linux)
            if rss > 1024:
                outcome = Outcome(
                    outcome.case,
                    outcome.family,
                    outcome.exit_code,
                    (*outcome.problems, f"peak RSS {rss:.0f} MiB"),
                    outcome.stderr,
                )
            results.append((outcome, elapsed, rss))
            if outcome.problems:
                key = hashlib.sha256(
                    (",".join(outcome.problems) + outcome.stderr[-120:]).encode()
                ).hexdigest()[:12]
                args.out.mkdir(exist_ok=True)
                target = args.out / f"{key}.mcap"
                if not target.exists():
                    target.write_bytes(case.data)
                    (args.out / f"{key}.txt").write_text(
                        f"{outcome.case}\n{outcome.problems}\n{outcome.stderr}\n"
                    )
            del running[pid]
            free.append(slot)
        if len(results) >= reported + 500:
            reported = len(results) // 500 * 500
            print(f"... {len(results)} cases, {time.time() - begun:.0f} s", flush=True)
    total = time.time() - begun
    print(f"\n{len(results)} cases in {total:.0f} s ({args.workers} workers, seed {args.seed})\n")
    print("| family | cases | exit 0 | exit 2 | exit 3 | problems |")
    print("|---|---|---|---|---|---|")
    for family in FAMILIES:
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


if __name__ == "__main__":
    main()

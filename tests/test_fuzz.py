"""Damaged and hostile logs: every mutated log ends in exit 0, 2 or 3, never a traceback.

Seeded structure-aware mutations (``tests/fuzzing.py``) of small logs written by dhlog's real
writers in all three encodings, run through ``dhlog process`` in this process. Each case must:
exit 0, 2 or 3; print no traceback; print one line on stderr for 2 and 3; leave the input
unchanged; leave no partial output. The long run is ``benchmarks/fuzz.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from fuzzing import FAMILIES, cases, run_in_process

CASES_PER_FAMILY = 36  # a family: 144 mutated logs a run (benchmarks/fuzz.py runs thousands)


@pytest.mark.parametrize("family", FAMILIES)
def test_mutated_logs_never_end_in_a_traceback(family: str, tmp_path: Path) -> None:
    failures = []
    seed = 100 + FAMILIES.index(family)
    for case in cases(CASES_PER_FAMILY, seed=seed, folder=tmp_path, families=(family,)):
        outcome = run_in_process(case, tmp_path)
        if outcome.problems:
            failures.append(f"{outcome.case}: {', '.join(outcome.problems)}: {outcome.stderr}")
    assert not failures, "\n".join(failures[:10])

"""Before/after of merging the terms the samples cannot tell apart (issue 31, item 5) on the
session of tests/test_cancelling_terms.py (a KR5 off its nominal, 40 random poses with the
flange pointing down within 0.5° and joints 4, 6 within ±0.5°, compliance on joints 2 and 3,
``--model compliance``): the run with the merge switched off (``beyond.cancelling`` finding
nothing) and as it stands, with the truth's deflections at the same samples.

    .venv/bin/python benchmarks/cancelling_terms.py
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))

from dhlog.identify.joints.sweeps import samples_with_encoders
from dhlog.identify.model import beyond
from test_cancelling_terms import _truth_deflection, short_wrist


def main() -> None:
    found = beyond.cancelling
    for label, rule in (("before", lambda *a, **k: []), ("after", found)):
        beyond.cancelling = rule
        session, r = short_wrist.__wrapped__()  # type: ignore[attr-defined]
        assert r.terms is not None and r.validation is not None
        _, Q, _ = samples_with_encoders(r.segmentation)
        want_joints, want_target = _truth_deflection(session, np.asarray(Q[:]))
        holds = sum("held at zero" in w for w in r.warnings)
        print(f"{label}: {r.terms.size} terms, {holds} held")
        for k in np.argsort(-np.abs(r.terms.coefficients))[:2]:
            print(f"  {r.terms.names()[k]} {r.terms.coefficients[k]:+.4g} ± {r.terms_std[k]:.3g}")
        print(
            f"  target {r.deflection_target * 1e3:.4f} ± {r.deflection_target_std * 1e3:.4f} mm"
            f" (truth {want_target * 1e3:.4f})"
        )
        arc = 180 / np.pi * 3600
        for i in (1, 2):
            print(
                f"  joint {i + 1} {r.deflection_max[i] * arc:.2f} ± "
                f"{r.deflection_max_std[i] * arc:.2f}″ (truth {want_joints[i] * arc:.2f}″)"
            )
        print(f"  FK RMS {r.validation.rms * 1e3:.5f} mm")
    beyond.cancelling = found


if __name__ == "__main__":
    main()

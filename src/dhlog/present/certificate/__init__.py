"""The calibration certificate (``dhlog report``): one self-contained HTML page of a result.

:func:`load_sources` (:mod:`.sources`) reads a result JSON (``<stem>.dh.json``), hashes it,
finds and hashes the log it names and reads ``<stem>.holdout.csv`` beside it;
:func:`certificate_html` (:mod:`.page`) turns those into the page: who and what was measured
(robot, dates, SHA-256 of the result and of the log), the tracker and noise model, the held-out
error before and after with a histogram beside the in-sample fit, the DH parameters with ±1σ and
measured − nominal (fixed ones marked with their reason, never shown as measurements), per-joint
residuals, the terms beyond the geometry, and the result's warnings and notes. A camera
calibration's result (its ``camera`` block) gets a camera section (:mod:`.camera_section`): the
set-up, the detections, the hand-eye poses ±1σ, the intrinsics and the corners, its held-out
check in pixels and mm in place of the tracker's.

Every byte read is untrusted: a missing, mistyped or damaged field is a
:class:`~.read.ResultFileError` naming the file and the field (:mod:`.read`, :mod:`.holdout`);
every text from the files is HTML-escaped (:mod:`.sections`). The page has no script and no
external resource (inline CSS; plots as inline SVG drawn by matplotlib, imported only by
:mod:`.plots`, with text as paths).
"""

from dhlog.present.certificate.page import certificate_html
from dhlog.present.certificate.sources import Nominal, load_sources

__all__ = ["Nominal", "certificate_html", "load_sources"]

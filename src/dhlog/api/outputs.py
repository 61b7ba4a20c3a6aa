"""What a calibration writes and where: the outputs' names beside a log
(:func:`output_names`), a run's files written together (:func:`write_run`), and the checks
every written file goes through (an input is never an output; written atomically)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from dhlog.errors import DhlogError, UsageError

if TYPE_CHECKING:
    from dhlog.identify.stages import Identification


class RunCalibration(Protocol):
    """What :func:`write_run` reads of a :class:`~dhlog.api.calibration.Calibration`: the run's
    record and the document it shows."""

    @property
    def run(self) -> Identification | None: ...

    document: dict[str, Any]


def output_names(path: str | Path, *, recording: bool, heldout: bool, terms: bool) -> list[Path]:
    """A run's outputs for ``path`` (``<stem>.dh.json``), in the order they are written: the JSON,
    the CSV table, the recording, the held-out poses' CSV (``heldout``: asked for), the terms'
    CSV (``terms``: terms beyond the geometry asked for)."""
    from dhlog.fleet.batch import HOLDOUT_SUFFIX, TERMS_SUFFIX

    target = Path(path)
    stem = target.name.removesuffix(".json").removesuffix(".dh")
    folder = target.parent
    outputs = [target, folder / f"{stem}.dh.csv"]
    if recording:
        outputs.append(folder / f"{stem}.rrd")
    if heldout:
        outputs.append(folder / f"{stem}{HOLDOUT_SUFFIX}")
    if terms:
        outputs.append(folder / f"{stem}{TERMS_SUFFIX}")
    return outputs


def write_run(
    calibration: RunCalibration,
    outputs: list[Path],
    units: str,
    *,
    with_log: bool = False,
    hold_signals: bool = False,
) -> None:
    """Write a run's ``outputs`` (:func:`output_names`) together, atomically; ``hold_signals``:
    an interrupt waits until they are in place (the command line)."""
    from dhlog.errors import OutputError
    from dhlog.fleet.batch import write_results

    if calibration.run is None:
        raise UsageError("a loaded calibration has no run to write; save() writes its JSON.")
    try:
        write_results(
            calibration.run,
            outputs,
            units,
            hold_signals=hold_signals,
            with_log=with_log,
            document=calibration.document,  # the JSON is the document the object shows
        )
    except OSError as exc:
        raise OutputError(outputs[0].parent, exc) from None


def _refuse_existing(path: Path, overwrite: bool, *inputs: str | Path | None) -> None:
    """An output that is one of the ``inputs`` (the log, a held-out log, a template …) is
    refused whatever ``overwrite`` says; an existing one unless ``overwrite``."""
    from dhlog.io.paths import refuse_inputs_as_outputs

    given = [(Path(p), "input") for p in inputs if p]
    try:
        refuse_inputs_as_outputs([(p, label) for p, label in given if p.exists()], [path])
    except DhlogError as exc:
        raise UsageError(f"{exc} Choose another path.") from None
    if path.exists() and not overwrite:
        raise UsageError(f"{path} exists; pass overwrite=True to replace it.")


def _write_text(path: Path, text: str) -> None:
    from dhlog.errors import OutputError
    from dhlog.io.writer import atomic_output

    try:
        with atomic_output(path) as f:
            f.write(text.encode())
    except OSError as exc:
        raise OutputError(path.parent, exc) from None

"""What a run says comes back as values: every stage of the identification returns its notes
(:class:`dhlog.errors.Note`: level, text, code) instead of appending to a list it was handed,
and the result keeps them in the order said, its ``warnings`` and ``info`` their texts."""

from __future__ import annotations

import ast
import dataclasses
import json
from pathlib import Path

import pytest

from dhlog.errors import Note, texts
from dhlog.identify.joints.checks import RMS_OUTLIER, check_fit_noise
from dhlog.identify.run import Identification, ProcessOptions, process_log
from dhlog.io.dhfile import load_dh
from dhlog.result.document import result_document

SRC = Path(__file__).parents[1] / "src" / "dhlog" / "identify"
SAMPLES = Path(__file__).parents[1] / "sample_logs"
#: The names a list of messages handed in to be appended to went by.
OUT_NAMES = {"notes", "warnings", "info", "said"}


def _out_parameters(tree: ast.AST) -> list[tuple[str, int, str]]:
    """Each function's parameters named as in :data:`OUT_NAMES` and annotated ``list[...]``
    (``list[str]``, ``list[Note]``): a list handed in to be appended to."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        args = node.args
        for arg in [*args.posonlyargs, *args.args, *args.kwonlyargs]:
            ann = arg.annotation
            if (
                arg.arg in OUT_NAMES
                and isinstance(ann, ast.Subscript)
                and isinstance(ann.value, ast.Name)
                and ann.value.id in ("list", "List")
            ):
                found.append((node.name, node.lineno, arg.arg))
    return found


def test_the_check_finds_an_out_parameter() -> None:
    """The check below fails on the form it looks for (and passes a returned tuple)."""
    source = (
        "def check(joints: list[int], notes: list[str]) -> None:\n    notes.append('x')\n"
        "def told(*, warnings: list[Note]) -> None: ...\n"
        "def fine(notes: tuple[Note, ...]) -> tuple[Note, ...]:\n    return notes\n"
    )
    assert _out_parameters(ast.parse(source)) == [("check", 1, "notes"), ("told", 3, "warnings")]


def test_no_function_in_identify_takes_a_list_of_messages_to_append_to() -> None:
    found = [
        f"{path.relative_to(SRC)}:{line} {name}({arg})"
        for path in sorted(SRC.rglob("*.py"))
        for name, line, arg in _out_parameters(ast.parse(path.read_text(encoding="utf-8")))
    ]
    assert not found, "\n".join(found)


def _appended_parameters(tree: ast.AST) -> list[tuple[str, int, str]]:
    """Each function's ``list[...]``-annotated parameters, of any name, that its body appends
    to (``.append``, ``.extend``, ``.insert``): a list handed in to be filled."""
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        args = node.args
        lists = {
            arg.arg
            for arg in [*args.posonlyargs, *args.args, *args.kwonlyargs]
            if arg.annotation is not None and ast.unparse(arg.annotation).startswith("list[")
        }
        for call in ast.walk(node):
            if (
                isinstance(call, ast.Call)
                and isinstance(call.func, ast.Attribute)
                and call.func.attr in ("append", "extend", "insert")
                and isinstance(call.func.value, ast.Name)
                and call.func.value.id in lists
            ):
                found.append((node.name, call.lineno, call.func.value.id))
    return found


def test_no_function_in_identify_fills_a_list_it_is_handed() -> None:
    """Of any name: what a stage finds comes back in its value (the check finds the form)."""
    assert _appended_parameters(
        ast.parse("def f(told: list[str]) -> None:\n    told.append('x')\n")
    )
    found = [
        f"{path.relative_to(SRC)}:{line} {name}({arg})"
        for path in sorted(SRC.rglob("*.py"))
        for name, line, arg in _appended_parameters(ast.parse(path.read_text(encoding="utf-8")))
    ]
    assert not found, "\n".join(found)


def test_a_note_has_a_level_a_text_and_a_code() -> None:
    said = Note.warning("joint 2: a sweep with only 3 sample(s) was set aside.", "short-sweep")
    assert (said.level, said.code) == ("warning", "short-sweep")
    assert Note.info("x", "y") == Note("info", "x", "y")
    with pytest.raises(ValueError, match="level 'implausible'"):
        Note("implausible", "x", "y")  # type: ignore[arg-type]
    with pytest.raises(dataclasses.FrozenInstanceError):
        said.text = "other"  # type: ignore[misc]
    notes = [Note.warning("a", "1"), Note.info("b", "2"), Note.warning("c", "3")]
    assert texts(notes, "warning") == ("a", "c") and texts(notes, "info") == ("b",)


@pytest.fixture(scope="module")
def kr5() -> Identification:
    log = SAMPLES / "kr5_0.1mm.mcap"
    return process_log(
        log, ProcessOptions(nominal=load_dh(log.with_name(log.stem + ".truth.json")))
    )


def test_a_joint_far_noisier_than_the_others_is_a_fit_noise_warning(kr5: Identification) -> None:
    """The fit-noise check on the sample's six joints: silent as measured; joint 3's fit RMS
    made 2 × :data:`RMS_OUTLIER` the others' median gives one warning, coded, naming it."""
    assert check_fit_noise(kr5.joints) == ()
    joints = [dataclasses.replace(j) for j in kr5.joints]
    rms = sorted(j.fit.rms for j in joints if j.fit is not None)
    typical = (rms[2] + rms[3]) / 2
    noisy = joints[2]
    assert noisy.fit is not None
    noisy = dataclasses.replace(
        noisy, fit=dataclasses.replace(noisy.fit, rms=2 * RMS_OUTLIER * typical)
    )
    joints[2] = noisy
    (said,) = check_fit_noise(joints)
    assert (said.level, said.code) == ("warning", "fit-noise")
    assert said.text.startswith(f"joint 3 ({noisy.name}): its fit RMS")


def test_the_result_s_warnings_and_notes_are_its_notes_texts_in_order(kr5: Identification) -> None:
    """``warnings`` and ``info`` are read off ``notes``, as the JSON's ``warnings`` and
    ``notes`` are; every note of a run carries a code."""
    assert kr5.notes and all(n.code for n in kr5.notes), kr5.notes
    assert kr5.warnings == tuple(n.text for n in kr5.notes if n.level == "warning")
    assert kr5.info == tuple(n.text for n in kr5.notes if n.level == "info")
    document = json.loads(json.dumps(result_document(kr5)))
    assert document["warnings"] == list(kr5.warnings)
    assert document["notes"] == list(kr5.info)
    added = kr5.said(Note.info("one more", "test"))
    assert added.notes[-1] == Note.info("one more", "test") and added.info[-1] == "one more"
    assert added.warnings == kr5.warnings


def test_a_step_and_measure_log_says_so_under_its_code() -> None:
    """No sweep moves while the tracker samples it: the clock offset's note, coded."""
    result = process_log(SAMPLES / "puma560_step.mcap")
    (said,) = [n for n in result.notes if n.code == "clock-offset"]
    assert said.level == "info" and "step-and-measure" in said.text
    assert said.text in result.info


def test_every_dataclass_of_the_identification_is_frozen() -> None:
    """A stage's value is built once and never changed (a later step makes a new one with
    ``dataclasses.replace``): every dataclass under ``dhlog.identify`` is frozen, the camera
    log's reader's counts too (built from what the walk met, after it)."""
    import importlib
    import pkgutil

    import dhlog.identify

    mutable = []
    for info in pkgutil.walk_packages(dhlog.identify.__path__, "dhlog.identify."):
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if (
                isinstance(obj, type)
                and obj.__module__ == info.name
                and dataclasses.is_dataclass(obj)
                and not obj.__dataclass_params__.frozen  # type: ignore[attr-defined]
            ):
                mutable.append(f"{info.name}.{name}")
    assert not mutable, f"mutable dataclasses in the identification: {mutable}"

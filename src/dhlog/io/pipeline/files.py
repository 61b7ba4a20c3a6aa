"""Pipelines from files: one read from its path (:func:`load_pipeline`, at most :data:`MAX_BYTES`),
the shipped ones (``pipelines/``: :func:`shipped_pipelines`, :func:`pipeline_by_name`) and either
by what the user gave (:func:`pipeline_from`: a path, or a shipped name, the nearest suggested).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from dhlog.errors import PipelineError
from dhlog.io.pipeline.parse import parse_pipeline
from dhlog.io.pipeline.spec import Pipeline

#: The largest pipeline file read (bytes).
MAX_BYTES = 1 * 2**20


def load_pipeline(path: str | Path) -> Pipeline:
    """Read a pipeline file (a regular file of at most :data:`MAX_BYTES`, UTF-8)."""
    from dhlog.io.textfile import decode_utf8, read_capped

    def fail(problem: str) -> PipelineError:
        return PipelineError(str(path), problem)

    data = read_capped(path, MAX_BYTES, fail, what="pipeline", hint="give the pipeline file.")
    return parse_pipeline(
        decode_utf8(data, fail, what="pipeline file"), str(path), folder=Path(path).parent
    )


def _shipped_files() -> list[tuple[str, str, Path | None]]:
    """The shipped pipelines' texts, names for messages and folders (None: a package's)."""
    folder = resources.files("dhlog").joinpath("pipelines")
    if not folder.is_dir():  # a source checkout: pipelines/ at the top level
        repo = Path(__file__).resolve().parents[4] / "pipelines"
        return [(f.read_text(encoding="utf-8"), str(f), None) for f in sorted(repo.glob("*.toml"))]
    return [
        (f.read_text(encoding="utf-8"), f"pipelines/{f.name}", None)
        for f in sorted(folder.iterdir(), key=lambda f: f.name)
        if f.name.endswith(".toml")
    ]


def shipped_pipelines(*, boards: bool = False) -> list[Pipeline]:
    """The pipelines shipped with dhlog, in order of preference; a camera pipeline's board and
    camera read only with ``boards`` (:func:`pipeline_by_name` reads them)."""
    found = [parse_pipeline(text, source, boards=boards) for text, source, _ in _shipped_files()]
    order = {"ros2_tracker": 0, "foxglove_json": 1, "foxglove_protobuf": 2}
    return sorted(found, key=lambda p: (order.get(p.name, 9), p.name))


def pipeline_by_name(name: str) -> Pipeline | None:
    """The shipped pipeline called ``name`` (a camera pipeline with its board), or None."""
    found = next((p for p in shipped_pipelines() if p.name == name), None)
    if found is None or not found.is_camera:
        return found
    text, source, _ = next(f for f in _shipped_files() if f[1] == found.source)
    return parse_pipeline(text, source)


def pipeline_from(spec: str) -> Pipeline:
    """A pipeline file, or a shipped pipeline by name (``dhlog pipelines`` lists them).

    A ``spec`` that is neither is an error listing the shipped names, with the nearest one
    (``ros2_trackr`` → ``ros2_tracker``)."""
    if not Path(spec).exists():
        shipped = pipeline_by_name(spec)
        if shipped is not None:
            return shipped
        import difflib

        names = [p.name for p in shipped_pipelines()]
        listed = ", ".join(names)
        if Path(spec).suffix == ".toml" or "/" in spec or "\\" in spec:  # meant as a file
            raise PipelineError(
                spec,
                f"no such pipeline file; check the path, or name a shipped pipeline ({listed}).",
            )
        near = difflib.get_close_matches(spec, names, n=1, cutoff=0.6)
        hint = f" (did you mean '{near[0]}'?)" if near else ""
        raise PipelineError(
            spec,
            f"is not a shipped pipeline{hint}; the shipped ones are {listed} (dhlog pipelines "
            "describes them), and a pipeline file of your own is given by its path.",
        )
    return load_pipeline(spec)

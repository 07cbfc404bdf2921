"""One store for every run that fills an output directory case by case (the paper's stripe
study, its study under phase measuring, a sweep): the directory held for the run, its
manifest read and compared with the new run's, what ``--overwrite`` removes, and the case
files written and read back. What differs between them is a :class:`Layout`: the names
of their files, which manifest keys let a new plan reuse case files, how a refusal names
what the directory holds. The rows and tables stay with the study and the sweep (their
thin stores call this one). No GL here.

A directory holds one manifest per layout (a JSON object): a run with another manifest
is refused unless ``overwrite``, which removes the old run's files first (and its case
files, but those a new plan of the same comparable settings reuses). Each finished case
is ``<cases>/<key>.json`` (:mod:`glshade.measure.case_files`: it vouches for itself),
written last, after its image ``<images>/<key>.png``: the mark a rerun looks for.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.files import (
    atomic_write_bytes,
    flush_files,
    make_inside,
    read_regular,
    remove_inside,
)
from glshade.measure.case_files import Rejected, case_file_bytes, read_case_file
from glshade.measure.locks import run_lock

#: A manifest as stored (None: the directory has none; {}: one that cannot be read).
Stored = dict[str, Any] | None
#: How a checked case file's record (without its case id and checksum) becomes a case's
#: record: ``read(data, key)`` gives the record, or None and why it is not one.
Reader = Callable[[dict[str, Any], str], tuple[Any, str | None]]


def _as_written(out_dir: Path, stored: Stored) -> Stored:
    return stored


@dataclass(frozen=True)
class Layout:
    """Where one kind of run keeps its files in an output directory, and what its refusal
    says. Layouts of other names share a directory without touching each other's files
    (the stripe study and the study under phase measuring).

    ``manifest``: its file; ``cases``: the folder of its case files; ``images``: the
    folder of their images (the case files' own folder where they sit beside them);
    ``files``: the glob patterns, at the top of the directory, of what ``--overwrite``
    removes (with the case files); ``comparable``: the manifest keys that change a case's
    numbers (where they are equal, a new plan reuses the case files it names);
    ``command``: the run, as the directory's lock names its holder; ``held``: what the
    directory holds, from the stored and the wanted manifest (the refusal's words);
    ``resume``: how to resume it; ``as_now``: a stored manifest (None where there is
    none) as this glshade writes it, the defaults of what an older one did not record
    filled in."""

    manifest: str
    held: Callable[[dict, dict], str]
    resume: str
    cases: str = "cases"
    images: str = "cases"
    files: tuple[str, ...] = ()
    comparable: tuple[str, ...] = ()
    command: str = "glshade paper"
    as_now: Callable[[Path, Stored], Stored] = _as_written


# --------------------------------------------------------------------------- manifest
def read_manifest(out_dir: Path, layout: Layout, what: str = "--out") -> Any:
    """The manifest's JSON (a regular file: a FIFO or device there is refused, never read);
    a missing or unreadable one raises."""
    return json.loads(read_regular(Path(out_dir) / layout.manifest, what))


def _stored(out_dir: Path, layout: Layout) -> Stored:
    """The directory's manifest as this glshade writes it: None where there is none, {}
    where it cannot be read (a run of unknown plan)."""
    path = Path(out_dir) / layout.manifest
    stored: Stored = None
    if path.exists() or path.is_symlink():
        try:
            found = read_manifest(out_dir, layout)
        except (ValueError, RecursionError):
            found = {}
        stored = found if isinstance(found, dict) else {}
    return layout.as_now(Path(out_dir), stored)


def changed(stored: Mapping, wanted: Mapping, keys: Iterable[str] | None = None) -> list[str]:
    """The manifest keys whose values differ: of ``keys``, in their order, or of both
    manifests, sorted."""
    names = sorted(set(stored) | set(wanted)) if keys is None else keys
    return [key for key in names if stored.get(key) != wanted.get(key)]


@contextmanager
def opened(
    out_dir: Path,
    layout: Layout,
    manifest: dict,
    overwrite: bool = False,
    *,
    keys: Collection[str] = (),
    images: bool = False,
) -> Iterator[list[Path]]:
    """``out_dir`` held for the run (:func:`glshade.measure.locks.run_lock`, in the name
    of ``layout.command``) and tied to ``manifest`` for the ``with`` block; gives the
    files removed.

    The directory is created (or reused) with its case folder (and its images' with
    ``images``) and its manifest written; one whose manifest differs from ``manifest``
    is refused, never mixed into and never overwritten unless ``overwrite``, which
    removes the old run's files first (``layout.files``, its case files and images),
    keeping the case files of ``keys`` (the new plan's) where the comparable settings
    are the same."""
    out_dir = Path(out_dir)
    with run_lock(out_dir, layout.command):
        yield _prepare(out_dir, layout, manifest, overwrite, keys, images)


def _prepare(
    out_dir: Path,
    layout: Layout,
    manifest: dict,
    overwrite: bool,
    keys: Collection[str],
    images: bool,
) -> list[Path]:
    """:func:`opened`'s work, with ``out_dir`` held (so made: :func:`~glshade.measure.locks.
    make_out_dir`)."""
    wanted = json.loads(json.dumps(manifest))  # as it reads back: lists, not tuples
    stored = _stored(out_dir, layout)
    removed: list[Path] = []
    if stored is not None and stored != wanted:
        if not overwrite:
            raise GlshadeError(
                f"--out {out_dir}: holds {layout.held(stored, wanted)}; rerun {layout.resume} "
                "to resume it, add --overwrite to replace it, or choose another --out"
            )
        same = all(stored.get(key) == wanted.get(key) for key in layout.comparable)
        removed = _remove_stale(out_dir, layout, keys if same else ())
    make_inside(out_dir, layout.cases)
    if images:
        make_inside(out_dir, layout.images)
    data = json.dumps(wanted, indent=2).encode()
    atomic_write_bytes(out_dir / layout.manifest, data, "--out", within=out_dir)
    return removed


def _remove_stale(out_dir: Path, layout: Layout, keep: Collection[str]) -> list[Path]:
    """Remove what ``--overwrite`` replaces: the layout's files at the top of ``out_dir``,
    and its case files and images but those of the cases ``keep``; only regular files
    inside ``out_dir`` (:func:`glshade.files.remove_inside`). Returns those removed."""
    top = [path for pattern in layout.files for path in sorted(out_dir.glob(pattern))]
    cases = [
        path
        for pattern in (f"{layout.cases}/*.json", f"{layout.images}/*.png")
        for path in sorted(out_dir.glob(pattern))
        if path.stem not in keep
    ]
    return [path for path in (*top, *cases) if remove_inside(out_dir, path)]


# --------------------------------------------------------------------------- case files
def _case_path(out_dir: Path, layout: Layout, key: str) -> Path:
    """Where case ``key``'s file is (or will be)."""
    return Path(out_dir) / layout.cases / f"{key}.json"


def write_case(
    out_dir: Path, layout: Layout, key: str, record: Mapping[str, Any], image: bytes | None
) -> None:
    """A finished case on disk: its image (a PNG) first, then its record (JSON-able) with
    its case id and checksum, the "done" mark a rerun looks for; each atomically."""
    out_dir = Path(out_dir)
    data = case_file_bytes(key, json.loads(json.dumps(record)))  # made before either write
    if image is not None:
        path = out_dir / layout.images / f"{key}.png"
        atomic_write_bytes(path, image, "--out", within=out_dir)
    atomic_write_bytes(_case_path(out_dir, layout, key), data, "--out", within=out_dir)


#: A finished case to write: its key, its record (JSON-able) and its image (PNG bytes) or
#: None.
CaseToWrite = tuple[str, Mapping[str, Any], bytes | None]


def write_cases(out_dir: Path, layout: Layout, cases: Sequence[CaseToWrite]) -> None:
    """Finished cases on disk as one group, each as :func:`write_case` leaves it, with one
    flush for the group instead of one a file. Every image first, atomically (temp file
    and rename) but not flushed; then the images' data and their folder flushed together
    (:func:`glshade.files.flush_files`); then every case file, atomically, the "done" mark
    a rerun looks for, not flushed at all. A case file vouches for itself (its case id and
    checksum, :mod:`~glshade.measure.case_files`): one whose data had not reached the disk
    when the machine stopped reads back missing or failing its check, and its case is
    measured again, never trusted half-written; an image cannot vouch for itself, so it
    is on the disk before the case file that marks it done is written."""
    out_dir = Path(out_dir)
    made = [
        (key, case_file_bytes(key, json.loads(json.dumps(record))), image)
        for key, record, image in cases
    ]  # every file's bytes made before any is written
    images = []
    for key, _, image in made:
        if image is not None:
            path = out_dir / layout.images / f"{key}.png"
            atomic_write_bytes(path, image, "--out", within=out_dir, flush=False)
            images.append(path)
    if images:
        flush_files(images, "--out")
    for key, data, _ in made:
        atomic_write_bytes(
            _case_path(out_dir, layout, key), data, "--out", within=out_dir, flush=False
        )


def _load_case(path: Path, key: str, read: Reader, rejected: Rejected | None = None) -> Any:
    """Case ``key``'s record from its file ``path``, or None: missing, or not to be trusted
    (:func:`~glshade.measure.case_files.read_case_file`: a failed checksum, another case's
    id, an older or interrupted writer; or what ``read`` finds), which ``rejected``
    collects with the reason: measure it again."""
    found = read_case_file(Path(path), key)
    record, problem = None, found.problem
    if found.record is not None:
        record, problem = read(found.record, key)
    if rejected is not None:
        rejected.add(Path(path), problem)
    return record if problem is None else None


def load_cases(
    out_dir: Path,
    layout: Layout,
    keys: Iterable[str],
    read: Reader,
    rejected: Rejected | None = None,
) -> dict[str, Any]:
    """The finished cases among ``keys``: their records by key, in the order of ``keys``
    (:func:`_load_case`; what is not trusted ``rejected`` collects)."""
    found = {}
    for key in keys:
        path = _case_path(out_dir, layout, key)
        record = _load_case(path, key, read, rejected)
        if record is not None:
            found[key] = record
    return found

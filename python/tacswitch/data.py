"""Reader of tacswitch datasets (``tacswitch simulate``), shared by training, evaluation and users.

``TactileDataset(root)`` is a map-style dataset: ``len(ds)`` and ``ds[i]`` -> a dict of numpy
arrays and labels. It needs no torch, yet ``torch.utils.data.DataLoader(ds, ...)`` accepts it as
is (a torch map-style Dataset is any object with ``__getitem__`` and ``__len__``).

Item keys (single contacts): ``image`` (I_wo) / ``image_markers`` (I_w) / ``reference``: uint8
BGR ``H x W x 3``; ``marker_mask`` / ``contact_mask``: ``H x W`` bool; ``rest``,
``displacement``: ``N x 2`` float32 ``(x, y)`` / ``(dx, dy)`` px; ``present``, ``merged``: ``N``
bool; ``label`` (str), ``label_id`` (int, index into ``classes``), ``params`` (dict), ``index``.
Sequences (``SequenceDataset``): the same per frame, stacked along a leading time axis
(``images``, ``images_markers``, ``marker_masks``, ``contact_masks``, ``displacements``), plus
``slip`` (``T`` bool), ``phase``, ``grasp_start`` and ``kind``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["SequenceDataset", "TactileDataset", "read_manifest"]


def read_manifest(root: str | Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """``(header, records)`` of the dataset in ``root`` (``dataset.json``, ``manifest.jsonl``)."""
    from tacswitch._checks import as_path

    root = Path(as_path(root, "root"))
    head = root / "dataset.json"
    man = root / "manifest.jsonl"
    if not head.is_file() or not man.is_file():
        raise ValueError(f"root: {str(root)!r} holds no tacswitch dataset "
                         "(dataset.json and manifest.jsonl expected)")
    try:
        header = json.loads(head.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"root: {str(head)!r} is not valid JSON ({exc})") from None
    if not isinstance(header, dict) or not isinstance(header.get("classes", []), list):
        raise ValueError(f"root: {str(head)!r} must hold a JSON object with a 'classes' list")
    records = []
    try:
        for n, line in enumerate(man.read_text().splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except ValueError as exc:
                raise ValueError(f"root: {str(man)!r} line {n} is not valid JSON ({exc})") from None
            if not isinstance(rec, dict):
                raise ValueError(f"root: {str(man)!r} line {n} is not a JSON object")
            records.append(rec)
    except UnicodeDecodeError as exc:
        raise ValueError(f"root: {str(man)!r} is not UTF-8 text ({exc})") from None
    return header, records


def _index(i: Any, n: int, what: str) -> int:
    """``i`` as an index into ``n`` items (negative from the end): ``TypeError`` /
    ``IndexError`` naming ``i`` otherwise."""
    if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
        raise TypeError(f"i: expected an integer index, got {type(i).__name__}")
    if not -n <= i < n:
        raise IndexError(f"i: {i} out of range for {n} {what}")
    return int(i) % n


def _record_dir(root: Path, rec: dict[str, Any], i: int) -> Path:
    """The folder of record ``i``; it must lie inside ``root`` (no absolute path, no ``..``)."""
    rel = rec.get("dir")
    if not isinstance(rel, str):
        raise ValueError(f"root: manifest record {i} has no 'dir' string")
    d = (root / rel).resolve()
    if not d.is_relative_to(root.resolve()):
        raise ValueError(f"root: manifest record {i} points outside the dataset ({rel!r})")
    return d


def _field(rec: dict[str, Any], key: str, i: int) -> Any:
    """``rec[key]``, or a ValueError naming the record and the missing key."""
    try:
        return rec[key]
    except (KeyError, TypeError):
        raise ValueError(f"root: manifest record {i} lacks {key!r}") from None


def _file(d: Path, rec: dict[str, Any], key: str, i: int) -> Path:
    """Path of file ``key`` of record ``i``, inside its folder ``d``."""
    files = _field(rec, "files", i)
    name = files.get(key) if isinstance(files, dict) else None
    if not isinstance(name, str):
        raise ValueError(f"root: manifest record {i} has no file {key!r}")
    path = (d / name).resolve()
    if not path.is_relative_to(d):
        raise ValueError(f"root: manifest record {i} file {key!r} points outside its folder")
    return path


def _classes(header: dict[str, Any], root: Any) -> list[str]:
    """The header's class names (``label_id`` indexes them); an error naming ``root`` when
    ``dataset.json`` has none."""
    if "classes" not in header:
        raise ValueError(f"root: {str(root)!r}: dataset.json lacks 'classes'")
    return list(header["classes"])


def _img(path: Path) -> np.ndarray:
    from tacswitch._io import read_image

    return read_image(path)


def _mask(path: Path, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """Reads a mask PNG as bool; ``shape``: the ``(H, W)`` it must have (its image's)."""
    import cv2

    m = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if m is None:
        raise ValueError(f"path: cannot read a mask from {str(path)!r}")
    if shape is not None and m.shape != tuple(shape[:2]):
        raise ValueError(f"path: mask {str(path)!r} is {m.shape[0]} x {m.shape[1]} but its image "
                         f"is {shape[0]} x {shape[1]}")
    return m > 127


class TactileDataset:
    """Single-contact samples of a dataset (see the module docstring).

    Args:
        root: dataset folder.
        transform: applied to each item dict before it is returned (e.g. to torch tensors).
        keys: load only these image keys (default all) — skipping images speeds up loading.
    """

    IMAGE_KEYS = ("image", "image_markers", "reference")
    MASK_KEYS = ("marker_mask", "contact_mask")

    def __init__(self, root: str | Path, *, transform: Callable[[dict], Any] | None = None,
                 keys: tuple[str, ...] | None = None) -> None:
        self.header, self.records = read_manifest(root)
        self.root = Path(root)
        if self.header.get("sequences"):
            raise ValueError(f"root: {str(root)!r} holds sequences; use SequenceDataset")
        self.classes: list[str] = _classes(self.header, root)
        self.transform = transform
        self.keys = keys

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, i: int) -> Any:
        n = _index(i, len(self), "samples")
        rec = self.records[n]
        d = _record_dir(self.root, rec, n)
        f = lambda key: _field(rec, key, n)  # noqa: E731
        try:
            item: dict[str, Any] = {
                "index": f("index"), "label": f("label"), "label_id": f("label_id"),
                "rest": np.asarray(f("rest"), np.float32).reshape(-1, 2),
                "displacement": np.asarray(f("displacement"), np.float32).reshape(-1, 2),
                "present": np.asarray(f("present"), bool),
                "merged": np.asarray(f("merged"), bool), "params": f("params"),
            }
        except (TypeError, ValueError) as exc:
            if str(exc).startswith("root:"):
                raise
            raise ValueError(f"root: manifest record {n} has a malformed field ({exc})") from None
        shape: tuple[int, ...] | None = None
        for k in self.IMAGE_KEYS:
            if self.keys is None or k in self.keys:
                item[k] = _img(_file(d, rec, k, n))
                shape = item[k].shape
        for k in self.MASK_KEYS:
            if self.keys is None or k in self.keys:
                item[k] = _mask(_file(d, rec, k, n), shape)
        return self.transform(item) if self.transform is not None else item

    def labels(self) -> np.ndarray:
        """Class ids of all samples (no image is read)."""
        return np.array([r["label_id"] for r in self.records], np.int64)


class SequenceDataset:
    """Grasp sequences of a dataset made with ``--sequences`` (see the module docstring)."""

    def __init__(self, root: str | Path, *, transform: Callable[[dict], Any] | None = None
                 ) -> None:
        self.header, self.records = read_manifest(root)
        self.root = Path(root)
        if not self.header.get("sequences"):
            raise ValueError(f"root: {str(root)!r} holds single samples; use TactileDataset")
        self.classes: list[str] = _classes(self.header, root)
        self.transform = transform

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, i: int) -> Any:
        n = _index(i, len(self), "sequences")
        rec = self.records[n]
        d = _record_dir(self.root, rec, n)
        try:
            item = self._load(rec, d, n)
        except (KeyError, TypeError, AttributeError) as exc:
            raise ValueError(f"root: manifest record {n} is malformed ({exc!r})") from None
        except ValueError as exc:
            if str(exc).startswith(("root:", "path:")):
                raise
            # e.g. np.stack of per-frame arrays of different lengths
            raise ValueError(f"root: manifest record {n} is malformed ({exc})") from None
        return self.transform(item) if self.transform is not None else item

    def _load(self, rec: dict[str, Any], d: Path, n: int) -> dict[str, Any]:
        fr = rec["frames"]
        if not isinstance(fr, list) or not fr:
            raise ValueError(f"root: manifest record {n} has no frames")
        reference = _img(_file(d, rec, "reference", n))
        shape = reference.shape

        def frames(key: str) -> np.ndarray:
            """Frame images ``key`` of every frame, each the reference's size."""
            out = []
            for t, f in enumerate(fr):
                im = _img(_file(d, f, key, n))
                if im.shape != shape:
                    raise ValueError(
                        f"root: manifest record {n} frame {t} {key!r} is {im.shape[0]} x "
                        f"{im.shape[1]} but its reference is {shape[0]} x {shape[1]}")
                out.append(im)
            return np.stack(out)

        item: dict[str, Any] = {
            "index": rec["index"], "kind": rec["kind"], "label": rec["label"],
            "label_id": rec["label_id"], "grasp_start": rec["grasp_start"],
            "reference": reference,
            "rest": np.asarray(rec["rest"], np.float32).reshape(-1, 2),
            "present": np.asarray(rec["present"], bool),
            "merged": np.asarray(rec["merged"], bool),
            "images": frames("image"),
            "images_markers": frames("image_markers"),
            "marker_masks": np.stack([_mask(_file(d, f, "marker_mask", n), shape) for f in fr]),
            "contact_masks": np.stack([_mask(_file(d, f, "contact_mask", n), shape)
                                       for f in fr]),
            "displacements": np.stack([np.asarray(f["displacement"], np.float32).reshape(-1, 2)
                                       for f in fr]),
            "slip": np.array([f["slip"] for f in fr], bool),
            "phase": [f["phase"] for f in fr], "params": rec["params"],
        }
        return item

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
    root = Path(root)
    head = root / "dataset.json"
    man = root / "manifest.jsonl"
    if not head.is_file() or not man.is_file():
        raise ValueError(f"root: {str(root)!r} holds no tacswitch dataset "
                         "(dataset.json and manifest.jsonl expected)")
    header = json.loads(head.read_text())
    records = [json.loads(line) for line in man.read_text().splitlines() if line.strip()]
    return header, records


def _img(path: Path) -> np.ndarray:
    from tacswitch._io import read_image

    return read_image(path)


def _mask(path: Path) -> np.ndarray:
    import cv2

    m = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if m is None:
        raise ValueError(f"path: cannot read a mask from {str(path)!r}")
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
        self.root = Path(root)
        self.header, self.records = read_manifest(self.root)
        if self.header.get("sequences"):
            raise ValueError(f"root: {str(root)!r} holds sequences; use SequenceDataset")
        self.classes: list[str] = list(self.header["classes"])
        self.transform = transform
        self.keys = keys

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, i: int) -> Any:
        if not -len(self) <= i < len(self):
            raise IndexError(f"i: {i} out of range for {len(self)} samples")
        rec = self.records[i]
        d = self.root / rec["dir"]
        item: dict[str, Any] = {
            "index": rec["index"], "label": rec["label"], "label_id": rec["label_id"],
            "rest": np.asarray(rec["rest"], np.float32).reshape(-1, 2),
            "displacement": np.asarray(rec["displacement"], np.float32).reshape(-1, 2),
            "present": np.asarray(rec["present"], bool),
            "merged": np.asarray(rec["merged"], bool), "params": rec["params"],
        }
        for k in self.IMAGE_KEYS + self.MASK_KEYS:
            if self.keys is not None and k not in self.keys:
                continue
            path = d / rec["files"][k]
            item[k] = _mask(path) if k in self.MASK_KEYS else _img(path)
        return self.transform(item) if self.transform is not None else item

    def labels(self) -> np.ndarray:
        """Class ids of all samples (no image is read)."""
        return np.array([r["label_id"] for r in self.records], np.int64)


class SequenceDataset:
    """Grasp sequences of a dataset made with ``--sequences`` (see the module docstring)."""

    def __init__(self, root: str | Path, *, transform: Callable[[dict], Any] | None = None
                 ) -> None:
        self.root = Path(root)
        self.header, self.records = read_manifest(self.root)
        if not self.header.get("sequences"):
            raise ValueError(f"root: {str(root)!r} holds single samples; use TactileDataset")
        self.classes: list[str] = list(self.header["classes"])
        self.transform = transform

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, i: int) -> Any:
        if not -len(self) <= i < len(self):
            raise IndexError(f"i: {i} out of range for {len(self)} sequences")
        rec = self.records[i]
        d = self.root / rec["dir"]
        fr = rec["frames"]
        item: dict[str, Any] = {
            "index": rec["index"], "kind": rec["kind"], "label": rec["label"],
            "label_id": rec["label_id"], "grasp_start": rec["grasp_start"],
            "reference": _img(d / rec["files"]["reference"]),
            "rest": np.asarray(rec["rest"], np.float32).reshape(-1, 2),
            "present": np.asarray(rec["present"], bool),
            "merged": np.asarray(rec["merged"], bool),
            "images": np.stack([_img(d / f["files"]["image"]) for f in fr]),
            "images_markers": np.stack([_img(d / f["files"]["image_markers"]) for f in fr]),
            "marker_masks": np.stack([_mask(d / f["files"]["marker_mask"]) for f in fr]),
            "contact_masks": np.stack([_mask(d / f["files"]["contact_mask"]) for f in fr]),
            "displacements": np.stack([np.asarray(f["displacement"], np.float32).reshape(-1, 2)
                                       for f in fr]),
            "slip": np.array([f["slip"] for f in fr], bool),
            "phase": [f["phase"] for f in fr], "params": rec["params"],
        }
        return self.transform(item) if self.transform is not None else item

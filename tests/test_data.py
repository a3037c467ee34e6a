"""Dataset writer (`tacswitch.sim.dataset`, `tacswitch simulate`) and reader (`tacswitch.data`)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from tacswitch.cli import simulate
from tacswitch.data import SequenceDataset, TactileDataset, read_manifest
from tacswitch.sim.dataset import generate_dataset


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def test_resume_skips_finished_and_redoes_partial(tmp_path: Path) -> None:
    out = tmp_path / "ds"
    first = generate_dataset(out, preset="gelsight_mini", n=3, seed=5, progress=False)
    assert first["generated"] == 3
    before = _files(out)
    # Simulate a crash inside item 1: its record (written last) is gone, an image is half there,
    # and a temporary file of an unfinished atomic write is left behind.
    (out / "samples/000001/record.json").unlink()
    (out / "samples/000001/image.png").write_bytes(b"partial")
    (out / "samples/000001/.image.png.x.tmp").write_bytes(b"junk")
    again = generate_dataset(out, preset="gelsight_mini", n=3, seed=5, progress=False)
    assert (again["generated"], again["skipped"]) == (1, 2)
    after = _files(out)
    after.pop("samples/000001/.image.png.x.tmp")
    assert after == before
    with pytest.raises(ValueError, match="other settings"):
        generate_dataset(out, preset="gelsight_mini", n=3, seed=6, progress=False)


def test_parallel_equals_serial_and_reader(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    generate_dataset(a, preset="gelsight_mini", n=3, seed=1, workers=1, progress=False)
    generate_dataset(b, preset="gelsight_mini", n=3, seed=1, workers=2, progress=False)
    assert _files(a) == _files(b)
    ds = TactileDataset(a)
    assert len(ds) == 3
    item = ds[2]
    assert item["image"].dtype == np.uint8 and item["image"].shape == (240, 320, 3)
    assert item["marker_mask"].dtype == bool
    assert np.array_equal(item["image"][~item["marker_mask"]],
                          item["image_markers"][~item["marker_mask"]])
    assert item["rest"].shape == item["displacement"].shape == (99, 2)
    assert ds.classes[item["label_id"]] == item["label"]
    assert ds.labels().shape == (3,)
    light = TactileDataset(a, keys=("image",), transform=lambda it: it["image"].mean())
    assert isinstance(light[0], float)
    with pytest.raises(IndexError):
        ds[3]
    header, records = read_manifest(a)
    assert header["n"] == 3 and [r["index"] for r in records] == [0, 1, 2]


def test_cli_sequences(tmp_path: Path) -> None:
    ap = argparse.ArgumentParser()
    simulate.add_parser(ap.add_subparsers())
    out = tmp_path / "seq"
    args = ap.parse_args(["simulate", "--preset", "gelsight_mini", "--n", "1", "--out", str(out),
                          "--sequences", "--frames", "8", "--workers", "1", "-q"])
    assert args.run(args) == 0
    ds = SequenceDataset(out)
    it = ds[0]
    assert it["images"].shape == (8, 240, 320, 3)
    assert it["slip"].shape == (8,) and it["kind"] in ("hold", "slip", "vibration")
    assert it["displacements"].shape[0] == 8
    rec = json.loads((out / "manifest.jsonl").read_text().splitlines()[0])
    assert rec["frames"][0]["phase"] == "press"
    with pytest.raises(ValueError, match="SequenceDataset"):
        TactileDataset(out)

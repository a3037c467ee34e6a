"""Writes simulated datasets: PNGs per sample plus one JSON Lines manifest with every label.

Layout of ``out``::

    dataset.json                 what was generated (preset, n, seed, options, classes)
    manifest.jsonl               one record per sample / sequence, sorted by index
    samples/000042/              image.png (I_wo), image_markers.png (I_w), reference.png,
                                 marker_mask.png, contact_mask.png (0/255), record.json
    sequences/000003/            frame_000.png, frame_000_markers.png, frame_000_mask.png,
                                 frame_000_contact.png, ..., reference.png, record.json

Item ``i`` is rendered from ``SeedSequence([seed, i])``, so the data do not depend on the number
of workers or on the order they finish in. Every file is written atomically and ``record.json``
last: an item is finished when its record exists and names files that exist, so rerunning skips
finished items (resume) and redoes half-written ones.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

FORMAT = "tacswitch-sim"
VERSION = 1


def _u8mask(m: np.ndarray) -> np.ndarray:
    return (np.asarray(m, bool) * np.uint8(255)).astype(np.uint8)


def _round(a: ArrayLike, nd: int = 4) -> list:
    return np.round(np.asarray(a, np.float64), nd).tolist()


def item_dir(out: Path, index: int, sequences: bool) -> Path:
    return out / ("sequences" if sequences else "samples") / f"{index:06d}"


def _finished(d: Path) -> dict | None:
    rec_path = d / "record.json"
    if not rec_path.is_file():
        return None
    try:
        rec = json.loads(rec_path.read_text())
    except (OSError, ValueError):
        return None
    files = rec.get("files", {})
    names = [v for v in files.values() if isinstance(v, str)]
    for fr in rec.get("frames", []):
        names += list(fr.get("files", {}).values())
    return rec if all((d / n).is_file() for n in names) else None


def generate_item(out: Path, index: int, seed: int, preset: str, sequences: bool,
                  options: dict[str, Any]) -> dict:
    """Renders and writes item ``index``; returns its manifest record."""
    from tacswitch._io import atomic_open, write_image
    from tacswitch.sim.indenters import CLASSES

    d = item_dir(out, index, sequences)
    rng = np.random.default_rng(np.random.SeedSequence([seed, index]))
    rel = d.relative_to(out).as_posix()
    if not sequences:
        from tacswitch.sim.scene import render_sample

        s = render_sample(preset, rng, optics=options.get("optics", "auto"),
                          vary_grid=options.get("vary_grid", False),
                          jpeg_quality=options.get("jpeg_quality"),
                          appearance=options.get("appearance", "preset"))
        files = {"image": "image.png", "image_markers": "image_markers.png",
                 "reference": "reference.png", "marker_mask": "marker_mask.png",
                 "contact_mask": "contact_mask.png"}
        write_image(d / files["image"], s.image)
        write_image(d / files["image_markers"], s.image_markers)
        write_image(d / files["reference"], s.reference)
        write_image(d / files["marker_mask"], _u8mask(s.marker_mask))
        write_image(d / files["contact_mask"], _u8mask(s.contact_mask))
        rec: dict[str, Any] = {
            "index": index, "dir": rel, "seed": [seed, index], "label": s.label,
            "label_id": CLASSES.index(s.label), "files": files,
            "rest": _round(s.rest), "displacement": _round(s.displacement),
            "present": s.present.tolist(), "merged": s.merged.tolist(), "params": s.params,
        }
    else:
        from tacswitch.sim.grasp import render_grasp

        kinds = options.get("kinds", ["hold", "slip", "vibration"])
        kind = kinds[int(rng.integers(len(kinds)))]
        g = render_grasp(preset, kind, n_frames=options.get("frames", 30), seed=rng,
                         optics=options.get("optics", "auto"),
                         jpeg_quality=options.get("jpeg_quality"),
                         appearance=options.get("appearance", "preset"))
        write_image(d / "reference.png", g.reference)
        frames = []
        for t, f in enumerate(g.frames):
            ff = {"image": f"frame_{t:03d}.png", "image_markers": f"frame_{t:03d}_markers.png",
                  "marker_mask": f"frame_{t:03d}_mask.png",
                  "contact_mask": f"frame_{t:03d}_contact.png"}
            write_image(d / ff["image"], f.image)
            write_image(d / ff["image_markers"], f.image_markers)
            write_image(d / ff["marker_mask"], _u8mask(f.marker_mask))
            write_image(d / ff["contact_mask"], _u8mask(f.contact_mask))
            frames.append({"files": ff, "displacement": _round(f.displacement),
                           "slip": g.slip[t], "phase": g.phase[t],
                           "object_offset": _round(g.object_offset[t]),
                           "stick_fraction": round(f.stick_fraction, 4)})
        rec = {
            "index": index, "dir": rel, "seed": [seed, index], "kind": kind,
            "label": g.scene.label, "label_id": CLASSES.index(g.scene.label),
            "files": {"reference": "reference.png"}, "grasp_start": g.grasp_start,
            "rest": _round(g.scene.rest), "present": g.scene.present.tolist(),
            "merged": g.scene.merged.tolist(), "frames": frames, "params": g.params,
        }
    # The record is the commit point of the item: written last, atomically.
    with atomic_open(d / "record.json") as fh:
        json.dump(rec, fh)
    return rec


def _worker(args: tuple) -> dict:
    import cv2

    cv2.setNumThreads(1)
    return generate_item(*args)


def _progress(done: int, total: int, t0: float, stream: Any) -> None:
    rate = done / max(time.perf_counter() - t0, 1e-9)
    width = 30
    fill = int(width * done / max(total, 1))
    stream.write(f"\r[{'#' * fill}{'.' * (width - fill)}] {done}/{total}  {rate:.2f} items/s")
    stream.flush()


def generate_dataset(out: str | Path, *, preset: str = "gelsight", n: int = 100, seed: int = 0,
                     sequences: bool = False, workers: int = 1, progress: bool = True,
                     options: dict[str, Any] | None = None,
                     on_item: Callable[[dict], None] | None = None) -> dict[str, Any]:
    """Generates (or completes) a dataset in ``out``; see the module docstring.

    Args:
        preset: sensor preset name. n: number of samples (or sequences). seed: dataset seed.
        sequences: grasp sequences instead of single contacts.
        workers: processes (results do not depend on it).
        options: ``optics``, ``vary_grid``, ``jpeg_quality``, ``appearance``, ``frames``,
            ``kinds``.

    Returns:
        A summary: ``{"generated", "skipped", "seconds", "items_per_s"}``.
    """
    from tacswitch._checks import as_jpeg_quality
    from tacswitch._io import atomic_open
    from tacswitch.sim.indenters import CLASSES
    from tacswitch.sim.presets import get_preset

    get_preset(preset)  # validate early
    if n < 0:
        raise ValueError(f"n: must be >= 0; got {n}")
    out = Path(out)
    opts = dict(options or {})
    if opts.get("jpeg_quality") is not None:
        # Checked before anything is written (OpenCV would silently clamp 101 or -1).
        opts["jpeg_quality"] = as_jpeg_quality(opts["jpeg_quality"])
    header = {"format": FORMAT, "version": VERSION, "preset": preset, "n": n, "seed": seed,
              "sequences": sequences, "options": opts, "classes": list(CLASSES)}
    head_path = out / "dataset.json"
    if head_path.is_file():
        old = json.loads(head_path.read_text())
        if {k: old.get(k) for k in ("preset", "seed", "sequences", "options")} != {
                k: header[k] for k in ("preset", "seed", "sequences", "options")}:
            raise ValueError(f"out: {out} holds a dataset made with other settings; "
                             "use another folder")
    with atomic_open(head_path) as fh:
        json.dump(header, fh, indent=1)
    records: dict[int, dict] = {}
    for i in range(n):
        rec = _finished(item_dir(out, i, sequences))
        if rec is not None:
            records[i] = rec
    todo = [i for i in range(n) if i not in records]
    skipped = n - len(todo)
    t0 = time.perf_counter()
    stream = sys.stderr
    jobs = [(out, i, seed, preset, sequences, opts) for i in todo]
    done = 0
    results: Iterator[dict]
    if workers <= 1 or len(jobs) <= 1:
        results = map(_worker, jobs)
        pool = None
    else:
        import multiprocessing as mp

        from tacswitch._checks import process_count

        pool = mp.get_context("spawn").Pool(process_count(workers, len(jobs)))
        results = pool.imap_unordered(_worker, jobs)
    try:
        for rec in results:
            records[rec["index"]] = rec
            done += 1
            if on_item is not None:
                on_item(rec)
            if progress:
                _progress(done, len(jobs), t0, stream)
    finally:
        if pool is not None:
            pool.terminate()
    if progress and jobs:
        stream.write("\n")
    secs = time.perf_counter() - t0
    with atomic_open(out / "manifest.jsonl") as fh:
        for i in sorted(records):
            fh.write(json.dumps(records[i]) + "\n")
    return {"generated": len(jobs), "skipped": skipped, "seconds": secs,
            "items_per_s": len(jobs) / secs if secs > 0 and jobs else 0.0}

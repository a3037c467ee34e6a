"""Writes Taxim's training presses (real markerless frames outside the proxy's held-out presses,
:func:`tacswitch.realproxy.training_presses`) as ``--paint`` folders for ``tacswitch train
tacdiff``: ``DIR/{gelsight,gelsight_mini}/press_NN.png``, their contact discs
``press_NN.contact.png`` and ``markers.json`` (the sensor's marker pitch and dot diameter, px).

Run: python benches/export_paint_frames.py DIR   (needs the taxim package: the test extra)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from tacswitch import realproxy
from tacswitch.sim.presets import get_preset


def export(root: Path) -> dict[str, int]:
    """Writes the folders; returns the number of presses per sensor."""
    counts = {}
    for sensor in realproxy.SENSORS:
        folder = root / sensor
        folder.mkdir(parents=True, exist_ok=True)
        presses = realproxy.training_presses(sensor)
        for i, frame, contact in presses:
            cv2.imwrite(str(folder / f"press_{i:02d}.png"), frame)
            cv2.imwrite(str(folder / f"press_{i:02d}.contact.png"),
                        contact.astype(np.uint8) * 255)
        preset = get_preset(sensor)
        # The dot diameter of the proxy's painted markers (realproxy.styles_for).
        diameter = realproxy.styles_for(sensor)["painted"].diameter
        held = sorted(realproxy.held_out_indices(sensor))
        (folder / "markers.json").write_text(json.dumps(
            {"pitch": preset.pitch, "diameter": diameter,
             "source": f"taxim {sensor} presses outside {held}"}))
        counts[sensor] = len(presses)
    return counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", type=Path)
    print(export(ap.parse_args().dir))


if __name__ == "__main__":
    main()

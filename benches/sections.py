"""The bench suite's sections: each ``##`` section of BENCHMARKS.md and the commands that make it.

Every table of BENCHMARKS.md sits under one ``##`` heading, and every heading is made by exactly
one section here (``tests/test_benches.py`` checks both ways). A section runs one or more bench
scripts of this folder, in order; ``quick`` is a smoke version of them (minutes at most, no
data outside the repository) where one exists; ``update`` names the one script that rewrites
the section in BENCHMARKS.md itself (through ``harness.publish``: the whole ``##`` section is
replaced by its notes, table and command) and the flag that makes it; it is set only where the
section holds that one script's output. Sections without ``update`` are curated by hand (several
scripts or tables, before/after comparisons): their scripts print the tables and the figures are
copied in with the date, machine and commit.

One-off studies whose conclusion is recorded live under ``benches/studies/`` (see its
README.md); they are not sections.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Section:
    """One section of the suite.

    Attributes:
        name: the runner's name for it (``python -m benches NAME``).
        heading: its ``##`` heading in BENCHMARKS.md (None: it feeds a guide, not BENCHMARKS).
        commands: the full run, per step: a script of ``benches/`` and its arguments, or
            ``"-m"`` and a module to run with ``python -m`` (e.g. the ``tacswitch`` CLI).
        quick: the smoke run (same shape), or None where there is none.
        update: ``(script, flag)``: the step that writes the section into BENCHMARKS.md.
        needs: what it needs beyond the base install (data, extras, a GPU), in words.
    """

    name: str
    heading: str | None
    commands: tuple[tuple[str, ...], ...]
    quick: tuple[tuple[str, ...], ...] | None = None
    update: tuple[str, str] | None = None
    needs: str = ""


REAL_SLIP = "../shared/data/real/gsmini_slip_train (the real GelSight Mini slip videos)"
TAXIM = "taxim's real presses unpacked with --taxim DIR (pip install taxim)"

SECTIONS: tuple[Section, ...] = (
    Section("extract", "## Marker extraction",
            (("bench_extract.py",),), quick=(("bench_extract.py", "--quick"),)),
    Section("extract-real",
            "## Marker extraction on real frames in contact with textured objects (issue #35)",
            (("check_extract_real.py", "--out", "bench-results/extract_real.json"),),
            quick=(("check_extract_real.py", "--limit", "2", "--step", "50"),),
            needs=REAL_SLIP),
    Section("match", "## Marker matching",
            (("bench_match.py",),), quick=(("bench_match.py", "--quick"),)),
    Section("tracker-scaling", "## Tracker scaling",
            (("bench_tracker_scaling.py", "--max-n", "1000000"),),
            quick=(("bench_tracker_scaling.py", "--quick"),)),
    Section("slip-real", "## Slip on real GelSight Mini grasps (learned grasp slip detector)",
            (("bench_slip_real.py",), ("bench_slip_real.py", "--markerless"),
             ("bench_slip_rates.py",), ("bench_slip_codecs.py",),
             ("bench_slip_incontact.py",)),
            needs=REAL_SLIP + "; torch and PyAV (the train extra) for the learned rows and "
                              "the H.264 re-encoding"),
    Section("slip-speed", "## Slip loop speed",
            (("bench_slip.py",), ("bench_slip_loop.py", "--rounds", "7")),
            quick=(("bench_slip.py", "--quick"),), needs=REAL_SLIP + " for the real-video rows"),
    Section("slip-simulated", "## Slip detection accuracy",
            (("bench_slip_accuracy.py", "--seeds", "6"),),
            quick=(("bench_slip_accuracy.py", "--seeds", "1"),)),
    Section("slip-markerless-simulated", "## Slip on a markerless sensor (simulated grasps)",
            (("bench_slip_markerless.py", "--seeds", "6", "--seed", "300", "--smooth-frames",
              "2", "--ref", "grasp_start"),),
            update=("bench_slip_markerless.py", "--update")),
    Section("cli-video", "## Command line: video output and grasp start",
            (("bench_cli_video.py", "--frames", "30", "--seeds", "4"),),
            quick=(("bench_cli_video.py", "--frames", "12", "--seeds", "1"),)),
    Section("motion-video-real",
            "## Markerless motion on real GelSight Mini videos (markers tracked, then removed)",
            (("bench_motion_video_real.py",),), needs=REAL_SLIP),
    Section("motion-sequence", "## Markerless motion over a sequence (from the no-contact frame)",
            (("bench_motion_sequence.py", "--every", "2", "--grasps", "3"),),
            quick=(("bench_motion_sequence.py", "--every", "12", "--grasps", "1"),),
            update=("bench_motion_sequence.py", "--update"), needs=TAXIM),
    Section("motion-model-real", "## Learned single-frame motion model on real frames",
            (("bench_motion_model_real.py",),), update=("bench_motion_model_real.py", "--update"),
            needs=TAXIM + "; the FOTS frames"),
    Section("motion-presets",
            "## Markerless motion: flow presets (speed, brightness, real-texture accuracy)",
            (("bench_motion_methods.py", "--repeat", "20", "--rounds", "5", "--every", "1"),),
            update=("bench_motion_methods.py", "--update"), needs=TAXIM),
    Section("motion-real-texture", "## Marker motion on real texture (proxy)",
            (("bench_motion_real.py", "--every", "2"),),
            quick=(("bench_motion_real.py", "--quick"),), needs=TAXIM),
    Section("tacdiff", "## TacDiff: averaging orientations (real frames first)",
            (("bench_prior_radius.py", "--frames", "4", "--seed", "0,1,2", "--models",
              "default=default,fast=fast", "--parts", "fots,proxy,sim", "--orientations",
              "1,4"),
             ("bench_tacdiff.py", "--frames", "2", "--rounds", "5", "--threads", "2")),
            needs=TAXIM + "; the FOTS frames"),
    Section("removal-real", "## Marker removal on real frames (real-frame proxy)",
            (("bench_real_removal.py", "--frames", "4"),),
            quick=(("bench_real_removal.py", "--quick"),),
            update=("bench_real_removal.py", "--update"), needs=TAXIM),
    Section("telea", "## TELEA inpainting",
            (("bench_telea.py",),), quick=(("bench_telea.py", "--quick"),),
            update=("bench_telea.py", "--update-md"), needs=TAXIM),
    Section("biharmonic", "## Biharmonic inpainting",
            (("bench_biharmonic.py",),), needs=TAXIM + "; scikit-image (the test extra)"),
    Section("merge", "## Patch merging",
            (("bench_merge.py",),), quick=(("bench_merge.py", "--quick"),),
            update=("bench_merge.py", "--update-md")),
    Section("finetune-real",
            "## TacDiff fine-tune: four training shifts, 1200 steps, a per-frame noise test "
            "(real frames with painted markers)",
            (("bench_finetune_real.py", "--seeds", "0", "--model", "default", "--sensors",
              "gelsight", "--codecs", "h264"),),
            needs=TAXIM + "; torch (the train extra); hours on a CPU"),
    Section("downstream", "## Downstream perception",
            (("-m", "tacswitch", "evaluate", "downstream", "--data",
              "bench-results/downstream"),),
            needs="torch and torchvision (the train extra); about an hour on 2 cores"),
    Section("simulator", "## Simulator",
            (("bench_sim.py", "--n", "20"), ("bench_sim.py", "--grain")),
            quick=(("bench_sim.py", "--n", "2"),), needs="taxim (the test extra)"),
    Section("cluster", "## Cluster conversion",
            (("bench_cluster.py", "--frames", "400", "--rounds", "3"),),
            quick=(("bench_cluster.py", "--frames", "8", "--rounds", "1"),),
            needs="Ray (the cluster extra)"),
    Section("device", None, (("bench_device.py",),),
            needs="onnxruntime-gpu and a GPU for the CUDA rows (docs/speed-and-accuracy.md)"),
)

#: Scripts of ``benches/`` that are neither a section's nor a study: shared code and tools.
SUPPORT = {
    "harness.py": "shared timing, table and BENCHMARKS.md writing code of the benches",
    "sections.py": "this registry",
    "__main__.py": "the runner (python -m benches)",
    "__init__.py": "makes benches a package for the runner",
    "bench_motion.py": "motion regression speed per architecture (feeds the model card)",
    "bench_native_builds.py": "two builds of the native core timed in alternating rounds "
                              "(before/after records of native speed work)",
    "export_paint_frames.py": "writes real frames with painted markers for the TacDiff GPU runs",
    "gpu_train_tacdiff.sh": "the recipe of the shipped TacDiff models on one GPU "
                            "(docs/your-own-sensor.md)",
}


def by_name() -> dict[str, Section]:
    """The sections by runner name."""
    return {s.name: s for s in SECTIONS}

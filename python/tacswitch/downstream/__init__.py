"""Downstream perception with and without markers (the paper's texture and contact study).

Does removing the markers help perception? The paper's experiment, on simulated frames whose
true markerless image is known:

- texture classification: ResNet-18 on the simulator's fabric texture classes;
- contact-area segmentation: DeepLabV3 (MobileNetV3-Large backbone, CPU-sized) on every
  contact class;

each trained per input type: the raw marker frames (``none``), OpenCV NS, our TELEA, TacDiff, the
hybrid mode, and the true markerless frames as the ceiling. Several seeds, paired across input
types (the same split, initialisation and batch order for every input of a seed), so a
difference can be told from the noise.

:mod:`~tacswitch.downstream.data` renders and inpaints the frames (numpy/onnxruntime, no torch);
:mod:`~tacswitch.downstream.study` trains and scores the models (torch, ``tacswitch[train]``).
``tacswitch evaluate downstream --data DIR`` runs it all.
"""

from tacswitch.downstream.data import INPUTS, StudyScale, build_dataset, load_dataset

__all__ = ["INPUTS", "StudyScale", "build_dataset", "load_dataset"]

"""Training-free motion methods of predict_motion: dense optical flow and the outward rule."""

from __future__ import annotations

import numpy as np
import pytest
from proxies import motion_proxy as proxy

from tacswitch import predict_motion
from tacswitch.motion import flow, heuristic


@pytest.mark.parametrize("method", ["flow", "outward"])
def test_identical_frames_give_zero_motion(mini, grid, method: str) -> None:
    for img in (mini.f0, mini.imgs[3]):
        m = predict_motion(img, img.copy(), grid, method=method)
        assert m.shape == grid.shape and m.dtype == np.float32
        assert np.abs(m).max() < 0.05


def _brighter(img: np.ndarray, gain: float, offset: float) -> np.ndarray:
    return np.clip(img.astype(np.float64) * gain + offset, 0, 255).astype(np.uint8)


@pytest.mark.parametrize("preset", [None, "balanced", "medium"])
def test_flow_ignores_a_global_brightness_change(mini, grid, preset) -> None:
    # None: the default preset ("refined"); the grid's outer rows sit 5.5 px from the edge.
    for img in (mini.f0, mini.imgs[5], mini.imgs[3]):
        for gain, offset in ((1.15, 5.0), (0.85, -5.0), (0.85, 0.0), (1.0, 8.0)):
            m = predict_motion(_brighter(img, gain, offset), img, grid, method="flow",
                               preset=preset)
            assert np.hypot(m[:, 0], m[:, 1]).max() < 0.2, (gain, offset)


def test_flow_ignores_a_global_brightness_change_at_640x480() -> None:
    gs = proxy.load_real_presses("gelsight")
    grid = proxy.marker_grid("gelsight")[0]
    for gain, offset in ((0.85, 0.0), (1.15, 5.0)):
        m = predict_motion(_brighter(gs.imgs[3], gain, offset), gs.imgs[3], grid)
        assert np.hypot(m[:, 0], m[:, 1]).max() < 0.2, (gain, offset)


def test_default_preset_is_refined_and_presets_differ(mini, grid) -> None:
    img, ref = mini.imgs[4], mini.f0
    assert flow.DEFAULT_PRESET == "refined"
    default = predict_motion(img, ref, grid, method="flow")
    np.testing.assert_array_equal(default, flow.flow_motion(img, ref, grid, preset="refined"))
    for other in ("balanced", "medium", "fast"):
        assert not np.array_equal(default, flow.flow_motion(img, ref, grid, preset=other))
    with pytest.raises(ValueError, match=r"^preset: unknown 'Refined'; choose from \['refined'"):
        flow.flow_motion(img, ref, grid, preset="Refined")


def test_refined_is_balanced_with_fewer_descent_and_more_refinement_steps() -> None:
    assert flow.REFINED["finest_scale"] == flow.BALANCED["finest_scale"]
    assert (flow.REFINED["gradient_descent_iterations"]
            < flow.BALANCED["gradient_descent_iterations"])
    assert (flow.REFINED["variational_refinement_iterations"]
            > flow.BALANCED["variational_refinement_iterations"])
    dis = flow._dis("refined")
    assert dis.getGradientDescentIterations() == flow.REFINED["gradient_descent_iterations"]
    assert (dis.getVariationalRefinementIterations()
            == flow.REFINED["variational_refinement_iterations"])


def test_the_imprint_suppression_reads_the_cached_reference_as_a_fresh_one(mini, grid) -> None:
    # The reference's grey is cached with its contrast: a second call (cache hit) and a call
    # after another reference (cache miss) give the same motion.
    img, ref = mini.imgs[4], mini.f0
    first = flow.flow_motion(img, ref, grid, suppress_imprint=True)
    np.testing.assert_array_equal(first, flow.flow_motion(img, ref, grid, suppress_imprint=True))
    flow.flow_motion(img, mini.imgs[2], grid, suppress_imprint=True)
    np.testing.assert_array_equal(first, flow.flow_motion(img, ref.copy(), grid,
                                                          suppress_imprint=True))


def test_refined_works_on_640x480_downsampled_in_the_callers_pixels() -> None:
    assert [flow.work_factor(w) for w in (320, 479, 480, 640, 1280)] == [1, 1, 2, 2, 4]
    assert flow.work_factor(640, preset="balanced") == 2
    assert flow.work_factor(640, preset="medium") == 1
    assert flow.work_factor(640, algorithm="farneback") == 1
    gs = proxy.load_real_presses("gelsight")
    grid = proxy.marker_grid("gelsight")[0]
    i = 5
    fld = proxy.random_field("shear", tuple(gs.centres[i]), float(gs.radii[i]), 40.0,
                             np.random.default_rng(2), shape=(480, 640))
    img = proxy.warp(gs.imgs[i], fld)
    true = fld.at(grid)
    pred = predict_motion(img, gs.imgs[i], grid)
    mag = np.linalg.norm(true, axis=1)
    assert mag.max() > 6.0
    # Motion in full-size pixels (x2 of the working size), read at the right markers.
    assert np.linalg.norm(pred - true, axis=1).mean() < 0.3 * mag.mean()
    moved = mag > 4.0
    cos = (pred[moved] * true[moved]).sum(1) / (np.linalg.norm(pred[moved], axis=1) * mag[moved])
    assert cos.mean() > 0.9


def test_padding_is_cropped_and_fits_tiny_frames() -> None:
    rng = np.random.default_rng(3)
    a = rng.integers(0, 256, (8, 400), dtype=np.uint8)
    b = np.roll(a, 1, axis=1)
    f = flow.dense_flow(a, b, pad=7)
    assert f.shape == (8, 400, 2)
    # A 400 px wide frame asks for 20 px of padding; an 8 px high one allows 7 at most.
    m = predict_motion(np.dstack([b] * 3), np.dstack([a] * 3), np.array([[200.0, 4.0]], np.float32))
    assert m.shape == (1, 2) and np.isfinite(m).all()
    # The smallest frames accepted (8 px a side; DIS alone refuses under 12 px): padded enough.
    for shape in ((8, 8), (8, 11), (11, 11)):
        small = rng.integers(0, 256, (*shape, 3), dtype=np.uint8)
        for preset in flow.DIS_PRESETS:
            m = predict_motion(small, np.roll(small, 1, axis=1), np.array([[4.0, 4.0]], np.float32),
                               preset=preset)
            assert m.shape == (1, 2) and np.isfinite(m).all(), (shape, preset)


@pytest.mark.parametrize("kind", ["shear", "twist", "press"])
def test_flow_recovers_a_known_warp_of_real_texture(mini, grid, kind: str) -> None:
    i = 2
    rng = np.random.default_rng(11)
    fld = proxy.random_field(kind, tuple(mini.centres[i]), float(mini.radii[i]), 20.0, rng,
                             shape=(240, 320))
    img = proxy.warp(mini.imgs[i], fld)
    true = fld.at(grid)
    pred = predict_motion(img, mini.imgs[i], grid, method="flow")
    err = np.linalg.norm(pred - true, axis=1)
    mag = np.linalg.norm(true, axis=1)
    assert mag.max() > 3.0
    assert err.mean() < 0.3 * mag.mean()
    moved = mag > 2.0
    cos = (pred[moved] * true[moved]).sum(1) / (np.linalg.norm(pred[moved], axis=1) * mag[moved])
    assert cos.mean() > 0.9


@pytest.mark.parametrize("algorithm", ["farneback", "pcaflow", "rlof", "deepflow"])
def test_other_flow_algorithms_follow_a_shift(mini, algorithm: str) -> None:
    import cv2

    # Quarter size keeps the slow contrib algorithms fast; a uniform shift of 2.5 px.
    src = cv2.resize(mini.imgs[1], (160, 120), interpolation=cv2.INTER_AREA)
    fld = proxy.Field("shear", (80.0, 60.0), [("shear", {"amp": 2.5, "rs": 1e6, "ex": 0.6,
                                                          "ey": 0.8, "k": 0.0})])
    img = proxy.warp(src, fld)
    pts = np.array([[60.0, 50.0], [100.0, 70.0], [80.0, 60.0]], np.float32)
    m = flow.flow_motion(img, src, pts, algorithm=algorithm)
    assert np.linalg.norm(m - np.array([1.5, 2.0]), axis=1).mean() < 0.8


def test_accurate_preset_follows_real_texture_and_works_on_the_callers_pixels() -> None:
    """``preset="accurate"`` (DeepFlow on the work-width frames) recovers a known shear of real
    GelSight texture at 640 x 480 (downsampled to 320 px wide and back to the caller's pixels)
    as closely as the default, and a brightness change stays under the 0.2 px bound."""
    gs = proxy.load_real_presses("gelsight")
    grid = proxy.marker_grid("gelsight")[0]
    src = gs.imgs[3]
    fld = proxy.Field("shear", (320.0, 240.0), [("shear", {"amp": 4.0, "rs": 1e6, "ex": 0.6,
                                                            "ey": 0.8, "k": 0.0})])
    img = proxy.warp(src, fld)
    true = fld.at(grid)
    err = {p: np.linalg.norm(predict_motion(img, src, grid, preset=p) - true, axis=1).mean()
           for p in ("refined", "accurate")}
    assert err["accurate"] < 0.25 * np.linalg.norm(true, axis=1).mean(), err
    assert err["accurate"] < err["refined"] + 0.3, err
    m = predict_motion(_brighter(src, 0.85, 0.0), src, grid, preset="accurate")
    assert np.hypot(m[:, 0], m[:, 1]).max() < 0.2
    assert flow.work_factor(640, "dis", "accurate") == 2


def test_accurate_preset_refuses_what_it_cannot_do(mini, grid) -> None:
    small = np.ascontiguousarray(mini.imgs[2][:40, :60])
    with pytest.raises(ValueError, match=r"^preset: 'accurate' needs frames at least 48 px"):
        predict_motion(small, np.roll(small, 1, axis=1), np.array([[10.0, 10.0]], np.float32),
                       preset="accurate")
    # A wide, low frame is downsampled to the work width: the limit is on the work frame.
    wide = np.ascontiguousarray(np.tile(mini.imgs[2][:80], (1, 2, 1)))  # 640 x 80 -> 320 x 40
    with pytest.raises(ValueError, match=r"^preset: 'accurate' needs frames at least 96 px"):
        predict_motion(wide, np.roll(wide, 1, axis=1), np.array([[10.0, 10.0]], np.float32),
                       preset="accurate")
    with pytest.raises(ValueError, match=r"^preset: 'accurate' is its own flow"):
        flow.flow_motion(mini.imgs[2], mini.f0, grid, algorithm="farneback", preset="accurate")
    assert "accurate" in flow.FLOW_PRESETS and "accurate" not in flow.DIS_PRESETS


def test_outward_rule_points_away_from_the_contact(mini, grid) -> None:
    i = 4
    c = mini.centres[i]
    for ref in (mini.f0, None):
        m = heuristic.outward_motion(mini.imgs[i], ref, grid)
        near = np.linalg.norm(grid - c, axis=1) < 2.5 * mini.radii[i]
        v = grid[near] - c
        cos = (m[near] * v).sum(1) / np.maximum(np.linalg.norm(m[near], axis=1)
                                                * np.linalg.norm(v, axis=1), 1e-9)
        assert np.median(cos) > 0.9
        assert np.abs(m).max() <= heuristic.OUTWARD_GAIN * 28.5 + 1e-3


def test_single_frame_background_ignores_the_imprint(mini) -> None:
    bg = heuristic.background(mini.imgs[4])
    d = heuristic.change_map(mini.imgs[4], None)
    c = np.round(mini.centres[4]).astype(int)
    assert bg.shape == (240, 320, 3)
    # The change is largest at the contact, small on the untouched gel.
    assert d[c[1], c[0]] > 4 * np.median(d)


def test_bad_inputs_name_the_argument(mini, grid) -> None:
    img = mini.imgs[0]
    with pytest.raises(ValueError, match=r"^method: unknown"):
        predict_motion(img, img, grid, method="magic")
    with pytest.raises(ValueError, match=r"^ref: shape"):
        predict_motion(img, img[:200], grid, method="flow")
    with pytest.raises(ValueError, match=r"^ref: shape"):
        predict_motion(img, img[:200], grid, method="outward")
    with pytest.raises(ValueError, match=r"^ref: method='flow'"):
        predict_motion(img, None, grid, method="flow")
    with pytest.raises(ValueError, match=r"^img: "):
        predict_motion(img[..., 0], img, grid, method="flow")
    with pytest.raises(TypeError, match=r"^ref: "):
        predict_motion(img, img.astype(np.float32), grid, method="flow")
    with pytest.raises(ValueError, match=r"^centres: "):
        predict_motion(img, img, grid[:, :1], method="flow")
    with pytest.raises(ValueError, match=r"^algorithm: unknown"):
        predict_motion(img, img, grid, method="flow", algorithm="lk")
    with pytest.raises(ValueError, match=r"^preset: unknown"):
        predict_motion(img, img, grid, method="flow", preset="slow")
    with pytest.raises(ValueError, match=r"^algorithm: applies to method='flow'"):
        predict_motion(img, img, grid, method="outward", algorithm="dis")


def test_default_centres_and_empty_centres(mini) -> None:
    m = predict_motion(mini.imgs[0], mini.f0, method="flow")
    assert m.shape == (99, 2)
    assert predict_motion(mini.imgs[0], mini.f0, np.zeros((0, 2)), method="flow").shape == (0, 2)


def test_cli_slip_markerless_flags_a_growing_shear_after_the_grasp_start(mini, tmp_path,
                                                                        capsys) -> None:
    import csv

    import cv2

    from tacswitch.cli import main

    i = 6
    folder = tmp_path / "rec"
    folder.mkdir()
    cv2.imwrite(str(tmp_path / "f0.png"), mini.f0)
    frames = [mini.f0] * 3 + [mini.imgs[i]] * 3
    # Then the contact is dragged sideways 1 px more every frame (slip threshold: 1.625 px).
    for k in range(1, 7):
        fld = proxy.Field("shear", tuple(mini.centres[i]),
                          [("shear", {"amp": float(k), "rs": 1.2 * float(mini.radii[i]),
                                      "ex": 1.0, "ey": 0.0, "k": 0.0})])
        frames.append(proxy.warp(mini.imgs[i], fld))
    for t, f in enumerate(frames):
        cv2.imwrite(str(folder / f"{t:03d}.png"), f)
    log = tmp_path / "log.csv"
    # Frames 3-5 are the same press (zero motion since the start); 1 px at frame 6 is below the
    # threshold, 2 px and more are above it. By default (markerless) the rule sees the mean of
    # the last 2 frames: 1.5 px at frame 7, 2.5 px at frame 8.
    for extra, first in (([], 8), (["--smooth-frames", "1"], 7)):
        assert main(["slip", str(folder), "--markerless", "--ref", str(tmp_path / "f0.png"),
                     "--start", "3", "--log", str(log), "-q", "--rule", "paper", *extra]) == 0
        rows = list(csv.DictReader(open(log)))
        flagged = [int(r["frame"]) for r in rows if r["slip"] == "1"]
        assert flagged and flagged[0] == first, extra
    capsys.readouterr()
    assert main(["slip", str(folder), "--ref", str(tmp_path / "f0.png"), "--log", str(log),
                 "-q"]) != 0
    assert capsys.readouterr().err.strip() == ("tacswitch slip: error: --ref: applies to "
                                               "--markerless only")


def test_default_method_is_flow_with_a_reference_and_the_ensemble_without(mini, grid) -> None:
    # (A no-contact reference makes "auto" run the ensemble: test_motion_reference.py.)
    img, ref = mini.imgs[4], mini.imgs[4][:, ::-1].copy()
    np.testing.assert_array_equal(predict_motion(img, ref, grid),
                                  predict_motion(img, ref, grid, method="flow"))
    ref = mini.f0
    np.testing.assert_array_equal(predict_motion(img, None, grid),
                                  predict_motion(img, None, grid, method="ensemble"))
    assert np.abs(predict_motion(ref, ref.copy(), grid)).max() < 0.05


def test_suppress_imprint_keeps_zero_and_the_brightness_bound(mini, grid) -> None:
    for img in (mini.f0, mini.imgs[3]):
        m = predict_motion(img, img.copy(), grid, method="flow", suppress_imprint=True)
        assert np.abs(m).max() == 0
    for img in (mini.f0, mini.imgs[5]):
        for gain, offset in ((1.15, 5.0), (0.85, -5.0), (1.0, 8.0)):
            m = predict_motion(_brighter(img, gain, offset), img, grid, method="flow",
                               suppress_imprint=True)
            assert np.hypot(m[:, 0], m[:, 1]).max() < 0.2, (gain, offset)
    # Untouched gel: the weight is ~1 under a gain change (matched by the median ratio); an
    # offset is not matched, but 3 grey levels still leave it above 0.8.
    g = flow._grey(mini.f0)
    assert flow.imprint_weight(g * 1.1, g).min() > 0.99
    assert flow.imprint_weight(g + 3.0, g).min() > 0.8


def test_suppress_imprint_trusts_the_flow_less_where_a_contact_appeared(mini, grid) -> None:
    # A real press against the real no-contact frame: the imprint's shading is not motion, and
    # plain flow follows it (several px at the contact). Suppressed: the weight is low at the
    # contact, high on the far gel, and the motion at the markers near the contact shrinks.
    for i in (2, 6):
        g, g0 = flow._grey(mini.imgs[i]), flow._grey(mini.f0)
        wt = flow.imprint_weight(g, g0)
        yy, xx = np.mgrid[:240, :320]
        disk = np.hypot(xx - mini.centres[i][0], yy - mini.centres[i][1]) < mini.radii[i]
        assert wt[disk].min() < 0.3 and np.median(wt) > 0.9
        near = np.linalg.norm(grid - mini.centres[i], axis=1) < 1.5 * mini.radii[i]
        plain = np.linalg.norm(predict_motion(mini.imgs[i], mini.f0, grid, method="flow")[near],
                               axis=1)
        supp = np.linalg.norm(predict_motion(mini.imgs[i], mini.f0, grid, method="flow",
                                             suppress_imprint=True)[near], axis=1)
        assert supp.mean() < 0.6 * plain.mean(), (supp.mean(), plain.mean())


def test_suppress_imprint_bad_inputs(mini, grid) -> None:
    img = mini.imgs[0]
    with pytest.raises(TypeError, match=r"^suppress_imprint: expected a bool"):
        predict_motion(img, mini.f0, grid, suppress_imprint="yes")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^suppress_imprint: applies to method='flow'"):
        predict_motion(img, mini.f0, grid, method="outward", suppress_imprint=True)


def test_cli_slip_markerless_ignores_texture_drifting_far_from_the_contact(mini, tmp_path,
                                                                          capsys) -> None:
    """A compressed video's texture can drift far from the contact (real H.264 does); slip is
    judged near the contact only, unless --all-markers."""
    import csv

    import cv2

    from tacswitch.cli import main

    i = 6
    cx, cy = mini.centres[i]
    h, w = mini.f0.shape[:2]
    # The corner block (a quarter of the width and height) farthest from the contact.
    bw, bh = w // 4, h // 4
    x0 = 0 if cx > w / 2 else w - bw
    y0 = 0 if cy > h / 2 else h - bh
    folder = tmp_path / "rec"
    folder.mkdir()
    cv2.imwrite(str(tmp_path / "f0.png"), mini.f0)
    frames = [mini.f0] * 3 + [mini.imgs[i]] * 3
    for k in range(1, 7):
        f = mini.imgs[i].copy()
        block = np.ascontiguousarray(f[y0:y0 + bh, x0:x0 + bw])
        shift = np.array([[1, 0, float(k)], [0, 1, 0]], np.float32)
        f[y0:y0 + bh, x0:x0 + bw] = cv2.warpAffine(block, shift, block.shape[1::-1],
                                                   borderMode=cv2.BORDER_REFLECT)
        frames.append(f)
    for t, f in enumerate(frames):
        cv2.imwrite(str(folder / f"{t:03d}.png"), f)
    log = tmp_path / "log.csv"
    flagged = {}
    for extra in ([], ["--all-markers"]):
        assert main(["slip", str(folder), "--markerless", "--ref", str(tmp_path / "f0.png"),
                     "--start", "3", "--log", str(log), "-q", "--rule", "paper", *extra]) == 0
        rows = list(csv.DictReader(open(log)))
        flagged[bool(extra)] = [int(r["frame"]) for r in rows if r["slip"] == "1"]
        valid = {int(r["valid_markers"]) for r in rows if int(r["frame"]) >= 3}
        assert valid == {99} if extra else (len(valid) == 1 and min(valid) < 99)
    assert flagged[False] == [] and flagged[True]
    capsys.readouterr()
    assert main(["slip", str(folder), "--all-markers", "--log", str(log), "-q"]) != 0
    assert capsys.readouterr().err.strip() == ("tacswitch slip: error: --all-markers: applies "
                                               "to --markerless only")


def _write_video(path, frames, codec: str) -> None:
    av = pytest.importorskip("av")
    out = av.open(str(path), "w")
    st = out.add_stream(codec, rate=25)
    st.height, st.width = frames[0].shape[:2]
    st.pix_fmt = "yuv420p" if codec == "libx264" else "yuvj420p"
    for f in frames:
        for pk in st.encode(av.VideoFrame.from_ndarray(f[..., ::-1].copy(), format="rgb24")):
            out.mux(pk)
    for pk in st.encode():
        out.mux(pk)
    out.close()


def test_cli_slip_markerless_warns_about_inter_frame_codecs(mini, tmp_path, capsys) -> None:
    from tacswitch.cli import main
    from tacswitch.cli.sources import INTER_FRAME_CODECS, video_codec

    frames = [mini.f0] * 3 + [mini.imgs[6]] * 3
    log = tmp_path / "log.csv"
    for codec, name, warned in (("libx264", "v.mp4", True), ("mjpeg", "v.avi", False)):
        _write_video(tmp_path / name, frames, codec)
        capsys.readouterr()
        assert main(["slip", str(tmp_path / name), "--markerless", "--log", str(log), "-q"]) == 0
        err = capsys.readouterr().err
        # (OpenCV's backends name H.264 'h264' or 'avc1'.)
        assert ("warning: source: " in err) is warned, err
        assert (video_codec(tmp_path / name) in INTER_FRAME_CODECS) is warned
    # Without --markerless (markers tracked, not predicted) nothing is said of the codec (this
    # markerless video may stop for want of markers, or track dark blobs from a later rest
    # frame: either way, no codec warning).
    main(["slip", str(tmp_path / "v.mp4"), "--log", str(log), "-q"])
    assert "inter-frame codecs" not in capsys.readouterr().err
    assert video_codec(tmp_path / "log.csv") is None


def test_cli_slip_markerless_says_when_the_start_frame_shows_no_contact(mini, tmp_path,
                                                                      capsys) -> None:
    """A video that starts in contact, without --ref: the first frame is the reference, the
    grasp-start frame shows no new contact against it, and every marker is judged (said)."""
    import cv2

    from tacswitch.cli import main

    folder = tmp_path / "rec"
    folder.mkdir()
    for t in range(6):
        cv2.imwrite(str(folder / f"{t:03d}.png"), mini.imgs[6])
    log = tmp_path / "log.csv"
    assert main(["slip", str(folder), "--markerless", "--start", "0", "--log", str(log),
                 "-q", "--rule", "paper"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning: --ref: the grasp-start frame shows no contact") == 1
    assert main(["slip", str(folder), "--markerless", "--start", "0", "--all-markers", "--log",
                 str(log), "-q"]) == 0
    assert "warning" not in capsys.readouterr().err


@pytest.mark.parametrize("shape", [(8, 40), (10, 40), (15, 400), (9, 1000), (8, 2000)])
def test_flow_on_short_wide_frames_is_finite(shape: tuple[int, int]) -> None:
    # DIS at its half-size finest scale crashed the process (OpenCV 5.0) on frames under 16 px
    # high, and the 320 px working width shrank a 9 x 1000 frame to 3 rows.
    rng = np.random.default_rng(0)
    ref = rng.integers(0, 255, (*shape, 3), np.uint8)
    img = np.roll(ref, 1, axis=1)
    c = np.array([[shape[1] / 2, shape[0] / 2]], np.float32)
    out = flow.flow_motion(img, ref, c)
    assert out.shape == (1, 2) and np.isfinite(out).all()
    assert flow.work_factor(shape[1], height=shape[0]) * 16 <= max(shape[0], 16)

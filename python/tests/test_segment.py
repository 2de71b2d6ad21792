"""`segment` on phantoms with known truth, and the README's NIfTI script."""

import re
import subprocess
import sys
from pathlib import Path

import nibabel as nib
import numpy as np
import pytest
import trimesh

import sparse_levelset as sl

ROOT = Path(__file__).resolve().parents[2]


def ball_phantom(n=48, radius=14.0, snr=4.0, seed=3, spacing=(1.0, 1.0, 1.0)):
    """A bright ball in Gaussian noise, indexed [i, j, k] with the given spacing."""
    rng = np.random.default_rng(seed)
    idx = np.indices((n, n, n)).astype(np.float64)
    c = (n - 1) / 2
    r = np.sqrt(sum(((idx[a] - c) * spacing[a] / spacing[0]) ** 2 for a in range(3)))
    truth = r <= radius
    image = 100.0 + 100.0 * truth + rng.normal(0, 100.0 / snr, truth.shape)
    return image, truth


def dice(a, b):
    return 2 * np.logical_and(a, b).sum() / (a.sum() + b.sum())


@pytest.mark.parametrize("method,kw", [
    ("threshold", dict(lower_threshold=150.0, upper_threshold=1000.0)),
    ("gac", {}),
    ("chan-vese", {}),
])
def test_methods_find_the_ball(method, kw):
    image, truth = ball_phantom()
    seg = sl.segment(image, method, seeds=[(24, 24, 24, 4)], **kw)
    assert seg.mask.shape == image.shape and seg.mask.dtype == np.uint8
    assert dice(seg.mask.astype(bool), truth) > 0.95
    r = seg.report
    assert r["stop"] in ("rms", "volume") and r["params"]["method"]["name"] == method
    mesh = trimesh.Trimesh(*seg.mesh()[:2], process=False)
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(truth.sum(), rel=0.05)


@pytest.mark.parametrize("method,kw", [
    ("threshold", dict(lower_threshold=150.0)),
    ("gac", {}),
    ("chan-vese", {}),
])
def test_the_fast_start_gives_the_seed_balls_mask_in_fewer_steps(method, kw):
    image, truth = ball_phantom()
    fast = sl.segment(image, method, seeds=[(24, 24, 24, 4)], **kw)
    balls = sl.segment(image, method, seeds=[(24, 24, 24, 4)], fast_start=False, **kw)
    assert balls.report["params"]["start_voxels"] is None
    assert 268 < fast.report["params"]["start_voxels"] < fast.report["voxels"]
    assert fast.report["iterations"] < balls.report["iterations"]
    differ = int((fast.mask != balls.mask).sum())
    assert differ * 200 <= truth.sum(), differ


def test_array_axes_and_spacing():
    # A C-ordered array indexed [z, y, x] with thick slices along axis 0: seeds and spacing
    # follow the array's axes, the mask has its shape.
    image, truth = ball_phantom(n=40, radius=12.0, spacing=(2.0, 1.0, 1.0))
    image = np.ascontiguousarray(image)
    # The ellipsoid reaches the array's faces along axes 1 and 2: without the guard's
    # leave, touching them would stop the run as a leak.
    seg = sl.segment(image, "threshold", seeds=[(20, 20, 20, 3)], spacing=(2.0, 1.0, 1.0),
                     lower_threshold=150.0, upper_threshold=1000.0, leak_guard=False)
    assert dice(seg.mask.astype(bool), truth) > 0.93
    v, f, _ = seg.mesh()
    # World = index × spacing: the ball's centre at 19.5 × spacing.
    np.testing.assert_allclose(trimesh.Trimesh(v, f).centroid, [39.0, 19.5, 19.5], atol=0.3)


def test_same_mask_for_any_thread_count_and_progress():
    image, _ = ball_phantom(n=40, radius=11.0)
    calls = []
    a = sl.segment(image, "gac", seeds=[(20, 20, 20)], threads=1, progress=calls.append)
    b = sl.segment(image, "gac", seeds=[(20, 20, 20)], threads=2)
    np.testing.assert_array_equal(a.mask, b.mask)
    assert a.levelset.checksum == b.levelset.checksum
    assert all("iteration" in c and "rms" in c for c in calls)


def test_an_exception_in_the_progress_callback_stops_the_run():
    image, _ = ball_phantom(n=40)

    def boom(info):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        sl.segment(image, "chan-vese", seeds=[(20, 20, 20)], number_of_iterations=100000,
                   maximum_rms_error=0.0, volume_change=0.0, progress=boom)


def test_nifti_image_with_its_header(tmp_path):
    image, truth = ball_phantom(n=40, radius=11.0, spacing=(1.0, 1.0, 2.5))
    affine = np.diag([1.0, 1.0, 2.5, 1.0])
    affine[:3, 3] = (-20.0, 5.0, 7.0)
    nib.save(nib.Nifti1Image(image.astype(np.int16), affine), tmp_path / "scan.nii.gz")
    im = sl.load_image(tmp_path / "scan.nii.gz")
    assert im.shape == [40, 40, 40] and im.spacing == [1.0, 1.0, 2.5]
    np.testing.assert_allclose(np.array(im.affine), affine)
    np.testing.assert_array_equal(im.array, image.astype(np.int16).astype(np.float32))
    seg = sl.segment(im, "gac", seeds=[(19.5, 19.5, 19.5, 3)])
    assert dice(seg.mask.astype(bool), truth) > 0.9
    seg.save_mask(tmp_path / "mask.nii.gz")
    saved = nib.load(tmp_path / "mask.nii.gz")
    np.testing.assert_allclose(saved.affine, affine)
    np.testing.assert_array_equal(np.asarray(saved.dataobj), seg.mask)
    # The mesh is in the scanner's world: the ball's centre through the affine.
    v, f, _ = seg.mesh()
    centre = affine[:3, :3] @ np.full(3, 19.5) + affine[:3, 3]
    np.testing.assert_allclose(trimesh.Trimesh(v, f).centroid, centre, atol=0.5)


def test_readme_script(tmp_path):
    """The README's Python example runs as printed, on a NIfTI file."""
    text = (ROOT / "README.md").read_text()
    block = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    assert len(block.strip().splitlines()) <= 15
    image, _ = ball_phantom(n=48)
    nib.save(nib.Nifti1Image(image.astype(np.float32), np.eye(4)), tmp_path / "scan.nii.gz")
    subprocess.run([sys.executable, "-c", block], cwd=tmp_path, check=True)
    mesh = trimesh.load(tmp_path / "surface.ply")
    assert mesh.is_watertight


def test_bad_input():
    image, _ = ball_phantom(n=20, radius=5)
    with pytest.raises(ValueError, match="seeds"):
        sl.segment(image, "gac")
    with pytest.raises(ValueError, match="unknown method"):
        sl.segment(image, "snakes", seeds=[(10, 10, 10)])
    with pytest.raises(ValueError, match="lower_threshold"):
        sl.segment(image, "threshold", seeds=[(10, 10, 10)])
    with pytest.raises(ValueError, match="seed"):
        sl.segment(image, "gac", seeds=[(10, 10)])
    bad = image.copy()
    bad[1, 2, 3] = np.inf
    with pytest.raises(ValueError, match="finite"):
        sl.segment(bad, "gac", seeds=[(10, 10, 10)])
    with pytest.raises(ValueError, match="spacing"):
        sl.segment(image, "gac", seeds=[(10, 10, 10)], spacing=(1, -1, 1))
    with pytest.raises(ValueError, match="shape"):
        sl.segment(image, "gac", init_mask=np.ones((3, 3, 3)))
    with pytest.raises(OSError):
        sl.load_image("/nonexistent/scan.nii.gz")


def test_docs_worked_example(tmp_path):
    """docs/python.md's worked example runs as printed."""
    text = (ROOT / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks
    subprocess.run([sys.executable, "-c", blocks[-1]], cwd=tmp_path, check=True,
                   stdout=subprocess.DEVNULL)
    assert (tmp_path / "ball.ply").exists()


def blurred_phantom(shape, inside, spacing=(1.0, 1.0, 1.0), noise=0.25, seed=11):
    """Another tool's convention: background 0, object 1, the indicator blurred by a
    one-voxel Gaussian, Gaussian noise (not `levelset phantom`'s 100/200 levels)."""
    from scipy import ndimage
    idx = np.indices(shape).astype(np.float64)
    pos = [idx[a] * spacing[a] for a in range(3)]
    truth = inside(*pos)
    rng = np.random.default_rng(seed)
    image = ndimage.gaussian_filter(truth.astype(np.float64), 1.0) + rng.normal(0, noise, shape)
    return image.astype(np.float32), truth


def test_an_open_threshold_window_keeps_the_whole_object():
    image, truth = blurred_phantom((40, 40, 40), lambda x, y, z: (x - 20) ** 2 + (y - 19) ** 2 + (z - 21) ** 2 <= 144)
    for upper in (None, 1e6, float("inf")):
        seg = sl.segment(image, "threshold", seeds=[(20, 19, 21, 3)], lower_threshold=0.5,
                         upper_threshold=upper)
        assert seg.report["stop"] in ("rms", "volume"), upper
        assert dice(seg.mask.astype(bool), truth) > 0.95, (upper, int(seg.mask.sum()), int(truth.sum()))


def test_a_flipped_affine_gives_an_outward_mesh_in_world_millimetres(tmp_path):
    image, truth = blurred_phantom((36, 36, 36), lambda x, y, z: (x - 15) ** 2 + (y - 18) ** 2 + (z - 19) ** 2 <= 81)
    affine = np.array([[-1.0, 0, 0, 100.0], [0, 1.0, 0, -20.0], [0, 0, 1.0, 5.0], [0, 0, 0, 1]])
    path = tmp_path / "flipped.nii.gz"
    nib.save(nib.Nifti1Image(image, affine), str(path))
    seg = sl.segment(sl.load_image(path), "chan-vese", seeds=[(15, 18, 19, 3)])
    assert dice(seg.mask.astype(bool), truth) > 0.95
    v, f, n = seg.mesh()
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.volume > 0
    assert mesh.volume == pytest.approx(4 / 3 * np.pi * 729, rel=0.06)
    # The centroid in world millimetres: voxel (15, 18, 19) through the affine.
    np.testing.assert_allclose(mesh.centroid, (affine @ [15, 18, 19, 1])[:3], atol=0.3)
    assert ((v - mesh.centroid) * n).sum(axis=1).min() > 0, "every normal points outward"


def test_an_anisotropic_segmentation_level_set_measures_the_world_volume():
    spacing = (1.0, 1.0, 2.5)
    image, truth = blurred_phantom(
        (40, 40, 24), lambda x, y, z: ((x - 20) / 12) ** 2 + ((y - 20) / 9) ** 2 + ((z - 30) / 18) ** 2 <= 1,
        spacing=spacing)
    seg = sl.segment(image, "chan-vese", seeds=[(20, 20, 12, 3)], spacing=spacing)
    assert dice(seg.mask.astype(bool), truth) > 0.95
    mask_volume = seg.mask.sum() * np.prod(spacing)
    ls = seg.levelset
    assert ls.voxel_size == 1.0
    assert ls.measure()["volume"] == pytest.approx(mask_volume, rel=0.01)


def test_a_leak_is_a_warning_and_a_flag():
    c = 24.0

    def shell(x, y, z):
        r = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2)
        hole = (x > c) & ((y - c) ** 2 + (z - c) ** 2 < 25)
        return (r >= 15) & (r <= 18) & ~hole

    image, _ = blurred_phantom((48, 48, 48), shell)
    with pytest.warns(sl.LeakWarning, match="leaked"):
        seg = sl.segment(image, "gac", seeds=[(c, c, c, 4)])
    assert seg.leaked and seg.report["stop"] == "leaked" and "face" in seg.report["leak"]
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quiet = sl.segment(image, "gac", seeds=[(c, c, c, 4)], leak_guard=False, number_of_iterations=200)
    assert not quiet.leaked



def test_a_segmentation_that_vanishes_warns():
    # GAC shrinking from a box over Gaussian noise: no object to stop on, nothing left.
    rng = np.random.default_rng(3)
    image = rng.normal(0.5, 0.1, (96, 96)).astype(np.float32)
    box = np.zeros(image.shape, np.uint8)
    box[10:-10, 10:-10] = 1
    with pytest.warns(sl.VanishedWarning, match="vanished"):
        seg = sl.segment(image, "gac", init_mask=box, propagation_scaling=-1)
    assert seg.vanished and seg.report["stop"] == "vanished" and seg.mask.sum() == 0
    assert seg.mask.shape == image.shape and not seg.leaked
    # A disc in the same noise is found, without a warning.
    y, x = np.mgrid[:96, :96]
    disc = (x - 48) ** 2 + (y - 48) ** 2 < 20**2
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        found = sl.segment(image + disc.astype(np.float32), "gac", init_mask=box, propagation_scaling=-1)
    assert not found.vanished and found.mask.sum() > 0


def test_chan_vese_that_tells_nothing_apart_warns():
    # A closed bright shell at SNR 2, seeded in its cavity of the background's intensity:
    # the region's mean ends within a noise level of the outside's.
    c = 32.0

    def shell(x, y, z):
        r = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2)
        return (r >= 20) & (r <= 24)

    image, _ = blurred_phantom((64, 64, 64), shell, noise=0.5)
    with pytest.warns(sl.ContrastWarning, match="not told apart"):
        cv = sl.segment(image, "chan-vese", seeds=[(c, c, c, 4)])
    assert cv.report["weak_contrast"] and cv.report["stop"] != "leaked"
    ball, _ = blurred_phantom((40, 40, 40), lambda x, y, z: (x - 20) ** 2 + (y - 20) ** 2 + (z - 20) ** 2 <= 144)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sl.segment(ball, "chan-vese", seeds=[(20, 20, 20, 3)]).report["weak_contrast"] is None


@pytest.mark.parametrize("method", ["gac", "chan-vese"])
def test_an_initial_level_set_is_read_by_its_zero_level(method):
    # A distance in voxels, the same ×100 (in ITK's examples an initial image is often a
    # steep or binary field) and a ±1 mask: the same front. Taken as they were, a steep
    # field left a few band voxels and the run stopped after one step with Dice 0.15.
    n = 128
    y, x = np.mgrid[:n, :n]
    truth = (x - 63.5) ** 2 + (y - 63.5) ** 2 < 30**2
    image = truth + np.random.default_rng(1).normal(0, 0.5, truth.shape)
    d = (np.hypot(x - 63.5, y - 63.5) - 10.0).astype(np.float32)
    masks = []
    for phi in (d, 100.0 * d, np.where(d < 0, -1.0, 1.0)):
        seg = sl.segment(image, method, init_levelset=phi)
        assert seg.report["iterations"] > 10
        assert dice(seg.mask, truth) > 0.99
        masks.append(seg.mask)
    assert dice(masks[0], masks[1]) > 0.999
    # In 3-D with anisotropic spacing too.
    image3, truth3 = ball_phantom(spacing=(1.0, 1.0, 2.0))
    idx = np.indices(image3.shape).astype(np.float64)
    r = np.sqrt((idx[0] - 23.5) ** 2 + (idx[1] - 23.5) ** 2 + ((idx[2] - 23.5) * 2.0) ** 2)
    d3 = (r - 6.0).astype(np.float32)
    seg = sl.segment(image3, method, spacing=(1.0, 1.0, 2.0), init_levelset=1000.0 * d3)
    assert dice(seg.mask, truth3) > 0.9


def test_scikit_image_starts_on_the_faces_end_as_one_voxel_in():
    # scikit-image's snakes start from masks that meet the array's edge (np.ones, a
    # rectangle from the edge): nothing beyond the array is inside at the start, so each
    # ends where the same start without its edge voxels ends. np.ones was refused ("no
    # interface"); the rectangle from the edge took a second disc that the start a voxel
    # in does not reach.
    y, x = np.mgrid[:120, :160]
    first = (x - 40) ** 2 + (y - 60) ** 2 < 35**2
    both = first | ((x - 120) ** 2 + (y - 60) ** 2 < 25**2)
    image = both + np.random.default_rng(11).normal(0, 0.3, both.shape)
    rect = np.zeros(both.shape, bool)
    rect[30:90, :60] = True
    for start, truth in ((np.ones(both.shape, bool), both), (rect, first)):
        inward = start.copy()
        inward[:, 0] = inward[:, -1] = inward[0, :] = inward[-1, :] = False
        a = sl.segment(image, "chan-vese", init_mask=start, leak_guard=False).mask
        b = sl.segment(image, "chan-vese", init_mask=inward, leak_guard=False).mask
        assert dice(a, truth) > 0.98
        assert dice(a, b) > 0.99

"""examples/record_video.py: one episode through Gymnasium's RecordVideo into an mp4 (and a GIF),
its frames those the environment renders, the files moved into place, errors named."""

import numpy as np
import pytest

pytest.importorskip("moviepy", reason="RecordVideo needs moviepy (pip install moviepy)")
iio = pytest.importorskip("imageio.v3", reason="reading the video back needs imageio (a moviepy dependency)")

from acc_gym.rendering import EGO, FRAME_SHAPE  # noqa: E402


def test_quick_run_writes_the_episodes_frames(run_example, tmp_path):
    out = tmp_path / "video"
    proc = run_example("record_video.py", "--quick", "--gif", "--gif-every", "5", "--out", str(out), "--name", "clip")
    assert sorted(p.name for p in out.iterdir()) == ["clip.gif", "clip.mp4"]  # no scratch folder left behind
    assert "singlelane/2/cut-in: 25 steps" in proc.stdout
    frames = iio.imread(out / "clip.mp4")
    assert frames.shape == (26, *FRAME_SHAPE)  # the reset's frame and one per step
    ego = np.all(np.abs(frames[0].astype(int) - EGO) <= 40, axis=-1)  # lossy codec: near the ego's blue
    assert ego.sum() > 200
    assert not np.array_equal(frames[1], frames[-1])  # the scene moves (dashes, HUD digits)
    from PIL import Image

    with Image.open(out / "clip.gif") as gif:
        assert gif.n_frames == 6 and gif.size == (FRAME_SHAPE[1], FRAME_SHAPE[0])  # frames 0, 5, ..., 25


def test_unknown_controller_and_bad_arguments(run_example, tmp_path):
    proc = run_example("record_video.py", "--quick", "--controller", "no-such", "--out", str(tmp_path), check=False)
    assert proc.returncode == 1 and "no-such" in proc.stderr and "acc" in proc.stderr
    assert not list(tmp_path.iterdir())  # nothing written, no scratch folder left
    proc = run_example("record_video.py", "--gif-every", "0", check=False)
    assert proc.returncode == 2 and "--gif-every" in proc.stderr

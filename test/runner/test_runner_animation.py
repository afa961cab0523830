"""The animated GIF of a run: decodes, one frame per drawn step, small, contacts flashing."""

import numpy as np
from PIL import Image, ImageSequence

from prvo_sim.animation import MAX_FRAMES, animate_run, contact_frames, frame_steps

GIF_LIMIT = 5 * 1024 * 1024


def crossing_run(step_count, dt=0.1):
    """Two robots of radius 0.25 crossing head-on along y = 0: in contact at t = 2 s only."""
    times = np.arange(step_count) * dt
    states = np.zeros((step_count, 2, 5))
    progress = np.minimum(times, 4.0)
    states[:, 0, 0] = -2.0 + progress
    states[:, 1, 0] = 2.0 - progress
    states[:, 0, 2], states[:, 1, 2] = 1.0, -1.0
    states[:, 1, 4] = np.pi
    goals = np.array([[2.0, 0.0], [-2.0, 0.0]])
    return times, states, goals, np.array([0.25, 0.25])


def test_frame_steps_cover_the_run_within_the_frame_limit():
    assert frame_steps(0).tolist() == []
    assert frame_steps(1).tolist() == [0]
    assert frame_steps(5, max_frames=10).tolist() == [0, 1, 2, 3, 4]
    # 500 steps in at most 150 frames: every 4th (ceil(499 / 149)) and the last.
    steps = frame_steps(500, max_frames=150)
    assert steps.tolist() == [*range(0, 500, 4), 499]
    for step_count in (2, 149, 150, 151, 1000, 6001):
        steps = frame_steps(step_count)
        assert steps[0] == 0 and steps[-1] == step_count - 1
        assert len(steps) <= MAX_FRAMES
        assert len(set(np.diff(steps)[:-1].tolist())) <= 1  # evenly spaced but for the last


def test_a_contact_between_frames_flashes_in_the_next_frame():
    times, states, _, radii = crossing_run(61)
    positions = states[..., :2]
    # Centres 0.5 m apart at t = 1.75 s and 2.25 s: in contact (separation < 0) in between.
    touching = np.abs(positions[:, 0, 0] - positions[:, 1, 0]) < 0.5
    assert touching.any()
    steps = np.arange(0, 61, 7)  # frames every 0.7 s: t = 2.1 s is drawn
    flashing = contact_frames(positions, radii, steps)
    expected = [bool(touching[(steps[frame - 1] + 1 if frame else 0):step + 1].any())
                for frame, step in enumerate(steps)]
    assert flashing[:, 0].tolist() == expected == flashing[:, 1].tolist()
    assert any(expected)


def test_gif_decodes_with_one_frame_per_drawn_step_and_stays_small(tmp_path):
    times, states, goals, radii = crossing_run(400)
    path = tmp_path / 'run.gif'
    frame_count = animate_run(path, times, states, goals, radii, ['a', 'b'], 'crossing',
                              position_std=[0.05, 0.05], scripted=[False, True])
    # ceil(399 / 149) = 3: steps 0, 3, ..., 399.
    assert frame_count == len(range(0, 400, 3)) == 134
    with Image.open(path) as image:
        assert image.format == 'GIF'
        frames = [frame.convert('RGB') for frame in ImageSequence.Iterator(image)]
        # The run's pace: 3 steps of 0.1 s a frame.
        assert image.info['duration'] == 300
    assert len(frames) == frame_count
    assert path.stat().st_size < GIF_LIMIT
    # Frames differ (the robots move); the contact frame (t = 2.1 s) has the flash colour.
    assert np.asarray(frames[0]).tolist() != np.asarray(frames[-1]).tolist()
    contact = np.asarray(frames[7]).astype(int)  # step 21: t = 2.1 s
    clear = np.asarray(frames[20]).astype(int)
    assert flash_pixels(contact) > 20 and flash_pixels(clear) == 0


def flash_pixels(frame):
    """Return how many pixels are the flash's red (odd frames) or gold (even frames)."""
    red = (frame[..., 0] > 230) & (frame[..., 1] < 30) & (frame[..., 2] < 30)
    gold = (frame[..., 0] > 230) & (np.abs(frame[..., 1] - 215) < 20) & (frame[..., 2] < 30)
    return int(np.count_nonzero(red | gold))


def test_headings_are_drawn_only_with_a_yaw_column(tmp_path):
    times, states, goals, radii = crossing_run(10)
    frames = {}
    for label, columns in (('yaw', 5), ('no_yaw', 4)):
        path = tmp_path / f'{label}.gif'
        animate_run(path, times, states[..., :columns], goals, radii, ['a', 'b'], 'x')
        with Image.open(path) as image:
            frames[label] = np.asarray(image.convert('RGB')).astype(int)
    # A heading is a black line inside the disc: only the yaw run has one.
    black = {label: int(np.count_nonzero(frame.sum(axis=-1) < 60))
             for label, frame in frames.items()}
    assert black['yaw'] > black['no_yaw']

"""The trajectory figure: a PNG with the paths, and contacts in red only when there are some."""

import matplotlib.image
import numpy as np

from prvo_sim.plotting import plot_run


def crossing_run():
    times = np.arange(0.0, 4.05, 0.1)
    positions = np.zeros((times.size, 2, 2))
    positions[:, 0, 0] = -2.0 + times
    positions[:, 1, 0] = 2.0 - times
    starts = positions[0]
    goals = np.array([[2.0, 0.0], [-2.0, 0.0]])
    return times, positions, starts, goals, np.array([0.25, 0.25])


def pure_red_pixels(path):
    image = matplotlib.image.imread(path)
    red, green, blue = image[..., 0], image[..., 1], image[..., 2]
    return int(np.count_nonzero((red > 0.9) & (green < 0.1) & (blue < 0.1)))


def test_png_written_with_contacts_marked_red(tmp_path):
    times, positions, starts, goals, radii = crossing_run()
    with_contact = tmp_path / 'contact.png'
    without_contact = tmp_path / 'clear.png'
    plot_run(with_contact, times, positions, starts, goals, radii, ['a', 'b'],
             [(2.0, 0, 1, 0.0)], 'crossing: 1 contact')
    plot_run(without_contact, times, positions, starts, goals, radii, ['a', 'b'], [],
             'crossing: no contact')
    for path in (with_contact, without_contact):
        assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert pure_red_pixels(with_contact) > 50
    assert pure_red_pixels(without_contact) == 0

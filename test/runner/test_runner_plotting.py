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


def test_scripted_robot_is_drawn_dashed_grey_and_hatched_with_a_legend_entry():
    import matplotlib.colors
    import matplotlib.pyplot as plt

    from prvo_sim.plotting import draw_trajectories

    times, positions, starts, goals, radii = crossing_run()
    positions[:, 1, 1] = 1.0  # the walker passes 1 m beside the robot
    figure, axes = plt.subplots()
    draw_trajectories(axes, times, positions, starts, goals, radii, [], labels=['a', 'walker'],
                      scripted=[False, True])
    paths = {line.get_label(): line for line in axes.get_lines()
             if not line.get_label().startswith('_')}
    assert set(paths) == {'a', 'walker (scripted)'}
    walker, robot = paths['walker (scripted)'], paths['a']
    assert walker.get_linestyle() == '--' and robot.get_linestyle() == '-'
    assert matplotlib.colors.same_color(walker.get_color(), 'grey')
    assert not matplotlib.colors.same_color(robot.get_color(), 'grey')
    hatched = [patch for patch in axes.patches if patch.get_hatch()]
    # Every disc of the walker, none of the robot: as many as the robot's plain discs.
    assert hatched and len(hatched) == len(axes.patches) // 2
    assert all(patch.center[1] == 1.0 for patch in hatched)
    plt.close(figure)

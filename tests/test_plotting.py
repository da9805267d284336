"""Episode plots: panels, lines per vehicle, mode ticks, atomic PNG saving."""

import os

import numpy as np
import pytest
from matplotlib.figure import Figure

from acc_gym.plotting import plot_episode, save_figure
from acc_gym.simulation.single_lane import Road, WorldTrace

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MODE_NAMES = ["ACCELERATE", "SAIL", "BRAKE", "EMERGENCY"]
VEHICLES = ("ego", "POV", "POV2")


def synthetic_trace(present=(True, True, False), T=20, dt=0.2):
    """One scene: the ego behind a POV that brakes; slot 2 as given; POV modes 0 -> 2, ego none."""
    S = len(present)
    t = np.arange(T + 1) * dt
    shape = (T + 1, 1, S)
    v = np.empty(shape)
    v[:, 0, :] = 20.0 + 0.1 * np.arange(S)
    v[:, 0, 1] -= np.linspace(0.0, 5.0, T + 1)
    x = np.cumsum(v * dt, axis=0) + 30.0 * np.arange(S)
    gap = np.full(shape, np.inf)
    gap[:, 0, 0] = x[:, 0, 1] - 4.7 - x[:, 0, 0]
    gap[: T // 2, 0, 1] = 40.0  # something ahead of the POV for the first half only
    mode = np.full(shape, -1, dtype=np.int64)
    mode[1:, 0, 1] = 0
    mode[T // 2:, 0, 1] = 2
    zeros = np.zeros(shape)
    return WorldTrace(t=t, x=x, v=v, a=np.gradient(v, dt, axis=0), a_des=zeros.copy(), y=zeros.copy(),
                      a_y=zeros.copy(), lead=np.zeros(shape, dtype=np.int64), gap=gap, mode=mode,
                      present=np.array([present]), lengths=np.full((1, S), 4.7), width=np.full((1, S), 1.8),
                      road=Road())


def vehicle_lines(ax):
    return [ln for ln in ax.get_lines() if ln.get_label() in VEHICLES]


def test_four_panels_and_lines_per_present_vehicle():
    trace = synthetic_trace(present=(True, True, False))
    fig = plot_episode(trace)
    assert isinstance(fig, Figure)
    assert len(fig.axes) == 4
    ax_v, ax_gap, ax_a, ax_mode = fig.axes
    assert [ln.get_label() for ln in vehicle_lines(ax_v)] == ["ego", "POV"]  # the absent POV2 is skipped
    assert len(vehicle_lines(ax_a)) == 2
    assert [ln.get_label() for ln in vehicle_lines(ax_gap)] == ["ego", "POV"]
    assert [ln.get_label() for ln in vehicle_lines(ax_mode)] == ["POV"]  # the ego has no mode
    np.testing.assert_allclose(vehicle_lines(ax_v)[1].get_ydata(), trace.v[:, 0, 1])
    np.testing.assert_allclose(vehicle_lines(ax_v)[0].get_xdata(), trace.t)
    # inf gaps are left blank (NaN), finite ones plotted as they are
    pov_gap = np.asarray(vehicle_lines(ax_gap)[1].get_ydata(), dtype=float)
    assert np.all(np.isnan(pov_gap[10:])) and np.all(pov_gap[:10] == 40.0)
    mode = np.asarray(vehicle_lines(ax_mode)[0].get_ydata(), dtype=float)
    assert np.isnan(mode[0]) and mode[1] == 0 and mode[-1] == 2
    # shared time axis, mode names as tick labels
    assert all(ax.get_shared_x_axes().joined(ax, ax_v) for ax in fig.axes)
    assert [t.get_text() for t in ax_mode.get_yticklabels()] == MODE_NAMES
    assert list(ax_mode.get_yticks()) == [0, 1, 2, 3]
    assert "[m/s]" in ax_v.get_ylabel() and "[m]" in ax_gap.get_ylabel() and "time" in ax_mode.get_xlabel()


def test_all_three_present():
    fig = plot_episode(synthetic_trace(present=(True, True, True)))
    assert [ln.get_label() for ln in vehicle_lines(fig.axes[0])] == list(VEHICLES)
    assert len(vehicle_lines(fig.axes[1])) == 2  # POV2 never has anyone ahead


def test_title_and_scenario(tmp_path):
    from types import SimpleNamespace

    sc = SimpleNamespace(id="singlelane/2/cut-in", seed=7, set_speed=25.0)
    fig = plot_episode(synthetic_trace(), title="my ACC", scenario=sc)
    text = fig.get_suptitle()
    assert "my ACC" in text and "singlelane/2/cut-in" in text and "7" in text
    set_speed = [ln for ln in fig.axes[0].get_lines() if ln.get_label() == "set speed"]
    assert len(set_speed) == 1 and np.all(np.asarray(set_speed[0].get_ydata()) == 25.0)
    assert len(vehicle_lines(fig.axes[0])) == 2


def test_path_writes_png_atomically(tmp_path):
    for target in (tmp_path / "episode.png", str(tmp_path / "second.png")):
        fig = plot_episode(synthetic_trace(), path=target)
        with open(target, "rb") as fh:
            assert fh.read(8) == PNG_SIGNATURE
        assert os.path.getsize(target) > 1000
        assert isinstance(fig, Figure)
    assert sorted(os.listdir(tmp_path)) == ["episode.png", "second.png"]  # no temporary file left


def test_save_figure_overwrites_and_cleans_up_on_failure(tmp_path):
    fig = plot_episode(synthetic_trace())
    target = tmp_path / "f.png"
    target.write_bytes(b"old")
    assert save_figure(fig, target) == target
    assert target.read_bytes()[:8] == PNG_SIGNATURE
    bad = tmp_path / "f.not-a-format"
    with pytest.raises(ValueError):
        save_figure(fig, bad)
    assert sorted(os.listdir(tmp_path)) == ["f.png"]  # neither the target nor a temporary file


def test_bad_scene_index():
    trace = synthetic_trace()
    with pytest.raises(ValueError, match="b must"):
        plot_episode(trace, b=1)
    with pytest.raises(ValueError, match="b must"):
        plot_episode(trace, b=-1)


def test_no_pyplot_figure_is_created():
    fig = plot_episode(synthetic_trace())
    assert fig.canvas.manager is None  # a bare Figure, not registered with pyplot


def test_works_on_a_simulated_trace(tmp_path):
    from acc_gym import scenarios
    from acc_gym.drivers import IDM, IDMParams

    sc = scenarios.build("singlelane/3/car-following+cut-in", seed=1)
    trace = scenarios.simulate(sc, IDM(IDMParams(v_desired=sc.set_speed), n=1, dt=sc.dt))
    fig = plot_episode(trace, scenario=sc, path=tmp_path / "run.png")
    n_present = int(trace.present[0].sum())
    ax_v, ax_gap, ax_a, ax_mode = fig.axes
    assert len(vehicle_lines(ax_v)) == len(vehicle_lines(ax_a)) == n_present
    has_gap = [s for s in range(trace.present.shape[1])
               if trace.present[0, s] and np.isfinite(trace.gap[:, 0, s]).any()]
    assert len(vehicle_lines(ax_gap)) == len(has_gap)
    has_mode = [s for s in range(trace.present.shape[1]) if trace.present[0, s] and (trace.mode[:, 0, s] >= 0).any()]
    assert has_mode and 0 not in has_mode  # MPC surrounding drivers report modes, the IDM ego none
    assert [ln.get_label() for ln in vehicle_lines(ax_mode)] == [VEHICLES[s] for s in has_mode]
    assert sc.id in fig.get_suptitle()
    assert (tmp_path / "run.png").read_bytes()[:8] == PNG_SIGNATURE


def test_panels_with_nothing_to_show_are_left_out():
    """No driver modes (every non-MPC episode): three panels, time on the acceleration panel;
    nobody ever ahead as well: two. The figure is shorter by what it leaves out."""
    trace = synthetic_trace(present=(True, True, False))
    four = plot_episode(trace)
    trace.mode[:] = -1
    fig = plot_episode(trace)
    assert [ax.get_ylabel() for ax in fig.axes] == ["speed [m/s]", "gap [m]", "acceleration [m/s$^2$]"]
    assert "time" in fig.axes[-1].get_xlabel()
    assert fig.get_figheight() < four.get_figheight()
    trace.gap[:] = np.inf
    fig = plot_episode(trace)
    assert [ax.get_ylabel() for ax in fig.axes] == ["speed [m/s]", "acceleration [m/s$^2$]"]

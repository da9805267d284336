"""Top-view frames: geometry, colours, clipping, validation, the world helper and the viewer."""

import time

import numpy as np
import pytest

from acc_gym.drivers.mpc import Mode
from acc_gym.rendering import EGO, LINE, MODE_COLOURS, NO_MODE, HumanViewer, frame_from_world, render_frame
from acc_gym.simulation.single_lane import Road

W, H, BEHIND, AHEAD = 640, 160, 30.0, 120.0
SX = W / (BEHIND + AHEAD)  # [px/m] independent of the module: the documented geometry
MARGIN = H // 10  # [px]
ROAD = Road(lane_width=3.75, n_lanes=2)
SY = (H - 2 * MARGIN) / (ROAD.n_lanes * ROAD.lane_width)  # [px/m]
L, WD = 4.7, 1.8  # [m]


def col(x, x_ego):
    return (x - (x_ego - BEHIND)) * SX


def row(y, road=ROAD):
    return MARGIN + ((road.n_lanes - 0.5) * road.lane_width - y) * SY


def scene(x, y=0.0, present=True, modes=None, **kw):
    x = np.asarray(x, dtype=float)
    return render_frame(x, np.broadcast_to(y, x.shape), np.broadcast_to(present, x.shape), L, WD, kw.pop("road", ROAD),
                        modes, **kw)


def colour_at(frame, r, c):
    return tuple(int(u) for u in frame[int(round(r)), int(round(c))])


def test_shape_and_dtype():
    frame = scene([100.0, 150.0])
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    assert scene([0.0], width_px=200, height_px=50).shape == (50, 200, 3)


def test_ego_drawn_at_its_position_in_ego_colour():
    for x_ego, y_ego in ((100.0, 0.0), (-37.0, 3.75), (1234.5, 1.0)):
        frame = scene([x_ego], y_ego)
        r, c = row(y_ego), col(x_ego - L / 2, x_ego)  # the rectangle's centre
        assert colour_at(frame, r, c) == EGO
        # the ego's extent along the road: front at col(x), rear at col(x - L)
        cols = np.flatnonzero(np.all(frame[int(round(r))] == EGO, axis=1))
        assert cols.min() >= round(col(x_ego - L, x_ego)) and cols.max() < round(col(x_ego, x_ego))
        assert cols.max() - cols.min() >= L * SX - 4  # outline is 1 px each side
        rows = np.flatnonzero(np.all(frame[:, int(round(c))] == EGO, axis=1))
        assert rows.min() >= round(row(y_ego + WD / 2)) and rows.max() < round(row(y_ego - WD / 2))
        assert rows.max() - rows.min() >= WD * SY - 4


def test_vehicle_50m_ahead_at_expected_column():
    x_ego = 200.0
    with_pov = scene([x_ego, x_ego + 50.0], modes=[-1, int(Mode.SAIL)])
    alone = scene([x_ego, x_ego + 50.0], present=[True, False])
    r = int(round(row(0.0)))
    changed = np.flatnonzero(np.any(with_pov[r] != alone[r], axis=1))
    assert abs(changed.min() - col(x_ego + 50.0 - L, x_ego)) <= 1
    assert abs(changed.max() + 1 - col(x_ego + 50.0, x_ego)) <= 1
    assert colour_at(with_pov, r, col(x_ego + 50.0 - L / 2, x_ego)) == MODE_COLOURS[int(Mode.SAIL)]


def test_window_follows_the_ego_and_moving_changes_the_frame():
    a = scene([100.0, 160.0])
    b = scene([100.0, 170.0])  # only the POV moves
    assert not np.array_equal(a, b)
    c = scene([110.0, 170.0])  # both move by 10 m: vehicles stay put, the dashes scroll
    r = int(round(row(0.0)))
    assert np.array_equal(a[r], c[r])  # the lane-0 centre row: vehicles only
    assert not np.array_equal(a, c)


def test_stepping_a_world_changes_the_frame(world):
    world.reset()
    before = frame_from_world(world)
    for _ in range(5):
        world.step(0.0)
    after = frame_from_world(world)
    assert before.shape == after.shape == (H, W, 3)
    assert not np.array_equal(before, after)


def test_absent_vehicle_not_drawn():
    alone = scene([100.0])
    absent = scene([100.0, 130.0, 160.0], present=[True, False, False], modes=[-1, 2, 3])
    assert np.array_equal(alone, absent)
    assert not np.array_equal(alone, scene([100.0, 130.0], present=[True, True]))


@pytest.mark.parametrize("dx", [500.0, -500.0, 1e9, AHEAD + L + 1.0, -BEHIND - 1.0])
def test_vehicle_beyond_the_view_not_drawn(dx):
    alone = scene([100.0])
    assert np.array_equal(alone, scene([100.0, 100.0 + dx], y=[0.0, 3.75]))


def test_vehicle_across_the_window_edge_is_clipped():
    x_ego = 0.0
    frame = scene([x_ego, x_ego + AHEAD + 2.0], y=[0.0, 3.75], modes=[-1, 0])  # front 2 m beyond the right edge
    r = int(round(row(3.75)))
    assert colour_at(frame, r, W - 1) == MODE_COLOURS[0]
    frame = scene([x_ego, x_ego - BEHIND + 1.0], y=[0.0, 3.75], modes=[-1, 0])  # 1 m of it visible at the left
    assert np.all(frame[r, 0] == MODE_COLOURS[0]) or np.all(frame[r, 1] == MODE_COLOURS[0])
    frame = scene([x_ego, x_ego], y=[0.0, 40.0])  # laterally far off the road
    assert np.array_equal(frame, scene([x_ego]))


def test_mode_colours_differ():
    modes = [-1, 0, 1, 2, 3]
    seen = []
    for m in modes:
        frame = scene([100.0, 150.0], y=[0.0, 3.75], modes=[-1, m])
        seen.append(colour_at(frame, row(3.75), col(150.0 - L / 2, 100.0)))
    assert len(set(seen)) == len(modes)
    assert seen[0] == NO_MODE and EGO not in seen
    assert seen[1:] == [MODE_COLOURS[int(m)] for m in (Mode.ACCELERATE, Mode.SAIL, Mode.BRAKE, Mode.EMERGENCY)]
    # the ego is always in the ego colour, whatever mode it is given
    frame = scene([100.0], modes=[int(Mode.BRAKE)])
    assert colour_at(frame, row(0.0), col(100.0 - L / 2, 100.0)) == EGO


def line_rows(frame):
    """Groups of consecutive rows holding lane-line pixels: (first, last, fraction of columns)."""
    is_line = np.all(frame == LINE, axis=2)
    rows = np.flatnonzero(is_line.any(axis=1))
    groups = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
    return [(g[0], g[-1], is_line[g[0]].mean()) for g in groups if g.size]


@pytest.mark.parametrize("n_lanes", [1, 2, 3, 4])
def test_lane_lines(n_lanes):
    road = Road(lane_width=3.5, n_lanes=n_lanes)
    frame = scene([100.0], road=road)
    groups = line_rows(frame)
    assert len(groups) == n_lanes + 1
    sy = (H - 2 * MARGIN) / (n_lanes * road.lane_width)
    for k, (first, last, frac) in enumerate(reversed(groups)):  # from the bottom: the road's right edge first
        centre = MARGIN + (n_lanes - k) * road.lane_width * sy
        assert first - 1 <= centre <= last + 2
        if k in (0, n_lanes):
            assert frac == 1.0  # solid road edges
        else:
            assert 0.2 < frac < 0.5  # dashed: 6 m in every 18 m


def test_dashes_scroll_with_the_road():
    dashed_row = line_rows(scene([100.0]))[1][0]  # two lanes: the middle group is the dashed line
    f1, f2 = scene([100.0]), scene([103.0])
    assert not np.array_equal(f1[dashed_row], f2[dashed_row])
    assert np.array_equal(f1, scene([100.0 + 18.0]))  # one dash period further: the same picture


def test_equal_aspect_keeps_proportions():
    frame = scene([100.0], aspect="equal")
    c = int(round(col(100.0 - L / 2, 100.0)))
    rows = np.flatnonzero(np.any(frame[:, c] != frame[:, c - 30], axis=1))  # the ego's column vs an empty one
    assert abs(rows.size - WD * SX) <= 2  # width WD at the horizontal scale
    road_rows = np.flatnonzero(np.any(frame[:, 5] != frame[0, 5], axis=1))
    assert abs(road_rows.size - ROAD.n_lanes * ROAD.lane_width * SX) <= 2
    assert abs(road_rows.mean() - (H - 1) / 2) <= 1.5  # centred


def test_speed_bar_follows_the_ego_speed():
    slow = scene([100.0], v=[5.0])
    fast = scene([100.0], v=[40.0])
    top = slice(0, MARGIN)
    n_slow = np.all(slow[top] == EGO, axis=2).sum()
    n_fast = np.all(fast[top] == EGO, axis=2).sum()
    assert 0 < n_slow < n_fast
    assert np.array_equal(scene([100.0])[MARGIN:], fast[MARGIN:])


@pytest.mark.parametrize("kwargs, name", [
    (dict(x=[0.0, np.nan]), "x"),
    (dict(x=[[0.0, 1.0]]), "x"),
    (dict(y=[0.0, 1.0, 2.0]), "y"),
    (dict(y=[0.0, np.inf]), "y"),
    (dict(present=[True]), None),  # broadcasts: fine
    (dict(present=[True, False, True]), "present"),
    (dict(lengths=[4.7, -1.0]), "lengths"),
    (dict(widths=[1.8, np.nan]), "widths"),
    (dict(modes=[0, 7]), "modes"),
    (dict(modes=[0, 1.5]), "modes"),
    (dict(modes=[0, 1, 2]), "modes"),
    (dict(v=[1.0, np.nan]), "v"),
    (dict(road=None), "road"),
    (dict(ego=2), "ego"),
    (dict(ego=-1), "ego"),
    (dict(width_px=0), "width_px"),
    (dict(height_px=12.5), "height_px"),
    (dict(view_ahead=-1.0), "view_ahead"),
    (dict(view_behind=np.inf), "view_behind"),
    (dict(aspect="stretch"), "aspect"),
    (dict(text=3), "text"),
])
def test_bad_inputs_raise_naming_the_argument(kwargs, name):
    args = dict(x=[0.0, 50.0], y=[0.0, 0.0], present=[True, True], lengths=[4.7, 4.7], widths=[1.8, 1.8], road=ROAD)
    args.update(kwargs)
    if name is None:
        assert render_frame(**args).shape == (H, W, 3)
        return
    with pytest.raises(ValueError, match=name):
        render_frame(**args)


def test_render_is_fast():
    x, y, p = np.array([100.0, 150.0, 180.0]), np.array([0.0, 3.75, 0.0]), np.ones(3, bool)
    times = []
    for _ in range(200):
        t0 = time.perf_counter()
        render_frame(x, y, p, L, WD, ROAD, [-1, 0, 2], [20.0, 25.0, 30.0])
        times.append(time.perf_counter() - t0)
    assert np.median(times) < 5e-3  # goal < 1 ms; generous for loaded CI machines


@pytest.fixture(scope="module")
def world():
    from acc_gym import scenarios

    scs = [scenarios.build("singlelane/3/car-following+cut-in", seed=s) for s in (1, 2)]  # MPC surrounding drivers
    return scenarios.make_world(scs)


def test_frame_from_world_reads_state_and_modes(world):
    world.reset()
    frame = frame_from_world(world)  # before any step: no modes yet
    b = 0
    x_ego = world.x[b, 0]
    sy = (H - 2 * MARGIN) / (world.road.n_lanes * world.road.lane_width)
    lane_row = lambda y: MARGIN + ((world.road.n_lanes - 0.5) * world.road.lane_width - y) * sy  # noqa: E731
    assert colour_at(frame, lane_row(world.y[b, 0]), col(x_ego - L / 2, x_ego)) == EGO
    assert colour_at(frame, lane_row(world.y[b, 1]), col(world.x[b, 1] - L / 2, x_ego)) == NO_MODE
    world.step(0.0)
    mode = int(world.driver_info(1)["mode"][b])
    frame = frame_from_world(world)
    x_ego = world.x[b, 0]
    assert colour_at(frame, lane_row(world.y[b, 1]), col(world.x[b, 1] - L / 2, x_ego)) == MODE_COLOURS[mode]
    forced = frame_from_world(world, modes=[-1, int(Mode.EMERGENCY), -1])
    assert colour_at(forced, lane_row(world.y[b, 1]), col(world.x[b, 1] - L / 2, x_ego)) == \
        MODE_COLOURS[int(Mode.EMERGENCY)]
    with pytest.raises(ValueError, match="b must"):
        frame_from_world(world, b=world.B)


def test_frame_from_world_per_scene(world):
    world.reset()
    world.step(0.0)
    frames = [frame_from_world(world, b=b) for b in range(world.B)]
    assert not np.array_equal(frames[0], frames[1])  # two different scenarios
    for b, frame in enumerate(frames):
        expected = render_frame(world.x[b], world.y[b], world.present[b], world.lengths[b], world.width[b],
                                world.road, [int(np.ravel(world.driver_info(s).get("mode", [-1] * world.B))[b])
                                             for s in range(world.S)], world.v[b])
        assert np.array_equal(frame, expected)


def test_human_viewer_lazy_and_headless(recwarn):
    import matplotlib

    matplotlib.use("Agg")
    viewer = HumanViewer()
    assert viewer._fig is None  # nothing opened on construction
    f1, f2 = scene([100.0, 150.0]), scene([100.0, 160.0])
    viewer.show(f1)
    fig = viewer._fig
    viewer.show(f2, text="t = 0.2 s")
    assert viewer._fig is fig  # one window, its image updated
    assert np.array_equal(np.asarray(viewer._image.get_array()), f2)
    with pytest.raises(ValueError, match="frame"):
        viewer.show(f1[..., 0])
    viewer.close()
    viewer.close()  # idempotent
    import matplotlib.pyplot as plt

    assert not plt.fignum_exists(fig.number)
    assert not [w for w in recwarn if "non-interactive" in str(w.message)]

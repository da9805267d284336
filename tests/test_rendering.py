"""Top-view frames: geometry, the gap, labels, the HUD, lane markings, text, the env's frames and the viewer.

Positions are measured in pixels of the drawing's own colours against the documented
geometry (acc_gym.rendering's module docstring), computed here independently of the module.
"""

import math

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the environments)
from acc_gym.drivers.mpc import Mode
from acc_gym.envs.registration import ENV_IDS
from acc_gym.rendering import (
    EGO, FRAME_SHAPE, GAP, HUD_BG, LINE, MODE_COLOURS, NO_MODE, OUTLINE, Q_BAD, Q_OK, Hud, HumanViewer, batch_hud,
    draw_text, font, frame_from_world, hud_rows, render_frame, text_width,
)
from acc_gym.simulation.single_lane import Road

H, W = FRAME_SHAPE[:2]
BEHIND, AHEAD = 30.0, 120.0
SX = W / (BEHIND + AHEAD)  # [px/m] independent of the module: the documented geometry
MARGIN = H // 10  # [px] (no HUD: the scene is the whole frame)
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


def is_colour(frame, colour):
    return np.all(frame == np.array(colour, np.uint8), axis=-1)


def test_shape_and_dtype():
    frame = scene([100.0, 150.0])
    assert frame.shape == FRAME_SHAPE and frame.dtype == np.uint8
    assert scene([0.0], width_px=200, height_px=50).shape == (50, 200, 3)
    hud = Hud(v=20.0, gap=30.0, set_speed=25.0, tau1=1.5, q=2.0, t=1.0)
    assert scene([0.0, 40.0], hud=hud, width_px=600, height_px=150).shape == (150, 600, 3)


def test_ego_drawn_at_its_position_in_ego_colour():
    for x_ego, y_ego in ((100.0, 0.0), (-37.0, 3.75), (1234.5, 1.0)):
        frame = scene([x_ego], y_ego)
        r, c = row(y_ego), col(x_ego - L / 2, x_ego)  # the rectangle's centre
        assert colour_at(frame, r, c) == EGO
        # the ego's extent along the road: front at col(x), rear at col(x - L)
        cols = np.flatnonzero(is_colour(frame[int(round(r))], EGO))
        assert cols.min() >= round(col(x_ego - L, x_ego)) and cols.max() < round(col(x_ego, x_ego))
        assert cols.max() - cols.min() >= L * SX - 4  # outline is 1 px each side
        rows = np.flatnonzero(is_colour(frame[:, int(round(c))], EGO))
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


@pytest.mark.parametrize("gap", [8.0, 23.4, 61.0])
def test_the_lead_is_drawn_the_gap_away_and_the_gap_line_spans_it(gap):
    x_ego = 500.0
    x_lead = x_ego + gap + L  # the lead's front bumper: its rear is `gap` ahead of the ego's front
    frame = scene([x_ego, x_lead], modes=[-1, int(Mode.BRAKE)], lead=1)
    r_centre = int(round(row(0.0)))
    r_body = int(round(row(0.0) - WD * SY / 4))  # a row through both bodies, off the gap line
    ego_cols = np.flatnonzero(is_colour(frame[r_body], EGO))
    lead_cols = np.flatnonzero(is_colour(frame[r_body], MODE_COLOURS[int(Mode.BRAKE)]))
    ego_front = ego_cols.max() + 2  # past the fill's last column and the 1 px outline
    lead_rear = lead_cols.min() - 1  # the outline's column
    assert abs((lead_rear - ego_front) - gap * SX) <= 1.5
    line = np.flatnonzero(is_colour(frame[r_centre], GAP))
    assert line.min() == ego_front and line.max() + 1 == lead_rear  # exactly between the two bodies
    assert np.all(is_colour(frame[r_centre - 1, line.min():line.max() + 1], GAP))  # 2 px thick
    label_rows = frame[r_centre + 2:r_centre + 2 + font(9).height, ego_front:lead_rear]
    labelled = np.count_nonzero(np.any(label_rows != frame[r_centre + 2:r_centre + 2 + font(9).height, 2:3], axis=-1))
    if text_width(f"{gap:.1f} m", 9) + 4 <= lead_rear - ego_front:
        assert labelled > 20  # the gap's length written under the line
    else:
        assert labelled == 0
    # without lead=, no gap line
    assert not np.any(is_colour(scene([x_ego, x_lead], modes=[-1, int(Mode.BRAKE)]), GAP))


def test_gap_line_clipped_at_the_window_edge():
    x_ego = 0.0
    frame = scene([x_ego, x_ego + AHEAD + 40.0], lead=1)  # the lead beyond the right edge
    line = np.flatnonzero(is_colour(frame[int(round(row(0.0)))], GAP))
    assert line.max() == W - 1 and abs(line.min() - col(x_ego, x_ego)) <= 1


def test_speed_labels_above_each_vehicle_follow_the_speed():
    x = [100.0, 140.0]
    base = scene(x, y=[0.0, 3.75])
    slow = scene(x, y=[0.0, 3.75], v=[10.0, 20.0])
    fast = scene(x, y=[0.0, 3.75], v=[10.0, 33.0])
    for s, (xs, ys) in enumerate(zip(x, [0.0, 3.75])):
        top = int(round(row(ys + WD / 2)))
        band = (slice(top - font(9).height, top), slice(int(col(xs - L, x[0])) - 8, int(col(xs, x[0])) + 8))
        assert np.count_nonzero(np.any(slow[band] != base[band], axis=-1)) > 10  # digits above the vehicle
        assert np.array_equal(slow[band], fast[band]) == (s == 0)  # only the changed vehicle's label changes
    for frame in (slow, fast):  # the labels sit above the bodies: those are untouched
        assert np.array_equal(is_colour(frame, EGO), is_colour(base, EGO))


def test_window_follows_the_ego_and_moving_changes_the_frame():
    a = scene([100.0, 160.0])
    b = scene([100.0, 170.0])  # only the POV moves
    assert not np.array_equal(a, b)
    c = scene([110.0, 170.0])  # both move by 10 m: vehicles stay put, the dashes scroll
    r = int(round(row(0.0)))
    assert np.array_equal(a[r], c[r])  # the lane-0 centre row: vehicles only
    assert not np.array_equal(a, c)


def test_absent_vehicle_not_drawn():
    alone = scene([100.0], v=[20.0])
    absent = scene([100.0, 130.0, 160.0], present=[True, False, False], modes=[-1, 2, 3], v=[20.0, 5.0, 9.0])
    assert np.array_equal(alone, absent)
    assert not np.array_equal(alone, scene([100.0, 130.0], present=[True, True], v=[20.0, 5.0]))


@pytest.mark.parametrize("dx", [500.0, -500.0, 1e9, AHEAD + L + 1.0, -BEHIND - 1.0])
def test_vehicle_beyond_the_view_not_drawn(dx):
    alone = scene([100.0], v=[20.0])
    assert np.array_equal(alone, scene([100.0, 100.0 + dx], y=[0.0, 3.75], v=[20.0, 30.0]))


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
    seen = []
    for m in [-1, 0, 1, 2, 3]:
        frame = scene([100.0, 150.0], y=[0.0, 3.75], modes=[-1, m])
        seen.append(colour_at(frame, row(3.75), col(150.0 - L / 2, 100.0)))
    assert len(set(seen)) == 5
    assert seen[0] == NO_MODE and EGO not in seen
    assert seen[1:] == [MODE_COLOURS[int(m)] for m in (Mode.ACCELERATE, Mode.SAIL, Mode.BRAKE, Mode.EMERGENCY)]
    frame = scene([100.0], modes=[int(Mode.BRAKE)])  # the ego is always in the ego colour
    assert colour_at(frame, row(0.0), col(100.0 - L / 2, 100.0)) == EGO


def line_rows(frame):
    """Groups of consecutive rows holding lane-line pixels: (first, last, fraction of columns)."""
    is_line = is_colour(frame, LINE)
    rows = np.flatnonzero(is_line.any(axis=1))
    groups = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
    return [(g[0], g[-1], is_line[g[0]].mean()) for g in groups if g.size]


@pytest.mark.parametrize("n_lanes", [1, 2, 3, 4])
def test_lane_lines(n_lanes):
    road = Road(lane_width=3.5, n_lanes=n_lanes)
    groups = line_rows(scene([100.0], road=road))
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


# ---------------------------------------------------------------------------------------------- HUD
HUD = Hud(v=25.0, gap=40.0, set_speed=30.0, tau1=1.5, q=3.2, t=12.2, lead_mode=int(Mode.SAIL), caption="a/b")


def test_hud_strip_on_top_and_the_scene_below_it():
    top = hud_rows(HUD)
    assert top == 2 * font(10).height + 4  # two lines and the padding
    frame = scene([100.0, 150.0], hud=HUD)
    assert np.all(frame[0, :] == HUD_BG) and np.all(frame[top - 1, :] == HUD_BG)
    # the scene is the documented geometry on the rows below the strip
    scene_px = H - top
    margin = scene_px // 10
    sy = (scene_px - 2 * margin) / (ROAD.n_lanes * ROAD.lane_width)
    rows = np.flatnonzero(is_colour(frame[:, int(round(col(100.0 - L / 2, 100.0)))], EGO))
    assert abs(rows.min() - 1 - (top + margin + (1.5 * ROAD.lane_width - WD / 2) * sy)) <= 1
    assert abs(rows.max() + 2 - (top + margin + (1.5 * ROAD.lane_width + WD / 2) * sy)) <= 1
    assert hud_rows(None) == 0 and hud_rows(None, "caption") == font(10).height + 4
    assert hud_rows(Hud(v=1.0)) == font(10).height + 4  # nothing for the second line


def test_hud_digits_follow_the_speed_and_nothing_else_changes():
    top = hud_rows(HUD)
    a = scene([100.0, 150.0], hud=HUD)
    b = scene([100.0, 150.0], hud=Hud(**{**HUD.__dict__, "v": 26.0}))
    assert np.array_equal(a, scene([100.0, 150.0], hud=HUD))  # the same state, the same picture
    changed = np.flatnonzero(np.any(a != b, axis=(0, 2)))
    assert changed.size and np.array_equal(a[top:], b[top:])  # only the HUD
    # the columns of the speed ("v  90.0 km/h") and of the time gap (gap / v), which follows it
    line = "".join(p for p, _ in HUD.lines()[0])
    adv, pad = font(10).advance, font(10).pad

    def field(start, n):
        return set(range(4 + start * adv, 4 + (start + n) * adv + 2 * pad))

    speed, headway = field(0, len("v  90.0 km/h")), field(line.index("time gap"), len("time gap 1.60 s"))
    assert set(changed.tolist()) <= speed | headway
    assert set(changed.tolist()) & speed and set(changed.tolist()) & headway
    for field, value in (("gap", 41.0), ("set_speed", 31.0), ("tau1", 1.2), ("t", 13.0), ("caption", "a/c")):
        assert not np.array_equal(a[:top], scene([100.0, 150.0], hud=Hud(**{**HUD.__dict__, field: value}))[:top]), \
            field


def test_hud_q_in_red_when_negative_green_otherwise():
    top = hud_rows(HUD)

    def count(frame, colour):
        return int(np.count_nonzero(is_colour(frame[:top], colour)))

    good = scene([100.0], hud=Hud(**{**HUD.__dict__, "q": 3.2}))
    bad = scene([100.0], hud=Hud(**{**HUD.__dict__, "q": -3.2}))
    none = scene([100.0], hud=Hud(**{**HUD.__dict__, "q": math.inf}))
    assert count(good, Q_OK) > 5 and count(good, Q_BAD) == 0
    assert count(bad, Q_BAD) > 5 and count(bad, Q_OK) == 0
    assert count(none, Q_BAD) == 0 and count(none, Q_OK) == 0


@pytest.mark.parametrize("field, value", [("v", math.nan), ("v", None), ("set_speed", math.inf), ("gap", math.nan),
                                          ("q", "3"), ("lead_mode", 7), ("caption", 3), ("t", math.nan)])
def test_bad_hud_fields_are_named(field, value):
    with pytest.raises(ValueError, match=f"Hud.{field}"):
        Hud(**{**HUD.__dict__, field: value})


def test_hud_lines_read_the_values():
    first, second = ("".join(p for p, _ in line) for line in HUD.lines())
    assert "v  90.0 km/h" in first and "set 108 km/h" in first and "gap  40.0 m" in first
    assert "time gap 1.60 s" in first and "tau1 1.50 s" in first and "Q   +3.2 m" in first
    assert "t  12.2 s" in second and "sail" in second and "a/b" in second
    first = "".join(p for p, _ in Hud(v=0.0, q=math.inf).lines()[0])
    assert "gap   -" in first and "time gap  -" in first and "Q   -" in first


# ---------------------------------------------------------------------------------------------- text
def test_text_is_drawn_where_asked_in_its_colour():
    frame = np.zeros((20, 120, 3), np.uint8)
    end = draw_text(frame, "Q 12", 3, 10, (255, 0, 0))
    f = font(10)
    assert end == 10 + 4 * f.advance
    inked = np.flatnonzero(frame[..., 0].any(axis=0))
    assert inked.min() >= 10 and inked.max() < 10 + text_width("Q 12")
    rows = np.flatnonzero(frame[..., 0].any(axis=1))
    assert rows.min() >= 3 and rows.max() < 3 + f.height
    assert frame[..., 1:].max() == 0 and frame[..., 0].max() == 255  # red only, fully covered somewhere
    right = np.zeros_like(frame)
    draw_text(right, "Q 12", 3, 110, (255, 0, 0), align="right")
    assert np.array_equal(right[:, 110 - text_width("Q 12"):110], frame[:, 10:10 + text_width("Q 12")])
    centre = np.zeros_like(frame)
    draw_text(centre, "Q 12", 3, 60, (255, 0, 0), align="centre")
    assert np.array_equal(np.roll(centre, -(60 - text_width("Q 12") // 2 - 10), axis=1)[:, :60], frame[:, :60])
    other = np.zeros_like(frame)
    draw_text(other, "Q 13", 3, 10, (255, 0, 0))
    assert not np.array_equal(other, frame)
    unknown, question = np.zeros_like(frame), np.zeros_like(frame)
    draw_text(unknown, "\u00b1", 3, 10, (255, 0, 0))
    draw_text(question, "?", 3, 10, (255, 0, 0))
    assert np.array_equal(unknown, question)
    draw_text(frame, "clipped at every edge", -5, -7, (0, 255, 0))  # no error; clipped
    with pytest.raises(ValueError, match="align"):
        draw_text(frame, "x", 0, 0, (0, 0, 0), align="middle")
    with pytest.raises(ValueError, match="colour"):
        draw_text(frame, "xy", 0, 0, [(0, 0, 0)] * 3)


def test_glyphs_do_not_depend_on_the_users_text_settings():
    import matplotlib

    reference = font(10).atlas.copy()
    font.cache_clear()
    try:
        with matplotlib.rc_context({"text.hinting": "no_hinting", "text.antialiased": False, "font.family": "serif",
                                    "font.size": 30}):
            assert np.array_equal(font(10).atlas, reference)
    finally:
        font.cache_clear()


# ---------------------------------------------------------------------------------------------- validation
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
    (dict(lead=0), "lead"),
    (dict(lead=2), "lead"),
    (dict(lead=-2), "lead"),
    (dict(lead=1), None),
    (dict(width_px=0), "width_px"),
    (dict(height_px=12.5), "height_px"),
    (dict(height_px=30, hud=HUD), "height_px"),
    (dict(view_ahead=-1.0), "view_ahead"),
    (dict(view_behind=np.inf), "view_behind"),
    (dict(aspect="stretch"), "aspect"),
    (dict(text=3), "text"),
    (dict(hud={"v": 3.0}), "hud"),
])
def test_bad_inputs_raise_naming_the_argument(kwargs, name):
    args = dict(x=[0.0, 50.0], y=[0.0, 0.0], present=[True, True], lengths=[4.7, 4.7], widths=[1.8, 1.8], road=ROAD)
    args.update(kwargs)
    if name is None:
        assert render_frame(**args).shape == FRAME_SHAPE
        return
    with pytest.raises(ValueError, match=name):
        render_frame(**args)


# ---------------------------------------------------------------------------------------------- worlds and envs
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
                                             for s in range(world.S)], world.v[b],
                                lead=int(world.neighbours.lead[b, 0]))
        assert np.array_equal(frame, expected)


@pytest.mark.filterwarnings("ignore:.*out of date")
@pytest.mark.parametrize("env_id", sorted(ENV_IDS))
def test_every_env_renders_its_scene_with_the_hud(env_id):
    env = gymnasium.make(env_id, render_mode="rgb_array")
    try:
        obs, _ = env.reset(seed=1)
        info = {}
        for _ in range(3):
            obs, _, term, trunc, info = env.step(np.array([0.0], np.float32))
            assert not (term or trunc)
        frame = env.render()
        assert frame.shape == FRAME_SHAPE and frame.dtype == np.uint8
        assert np.array_equal(frame, env.render())  # rendering does not change the state
        core = env.unwrapped.core
        hud = batch_hud(core)
        top = hud_rows(hud)
        assert np.all(frame[0] == HUD_BG) and np.count_nonzero(is_colour(frame[top:], EGO)) > 50
        # the lane markings of the scenario's road: n_lanes + 1 lines, solid edges, dashed between
        groups = line_rows(frame[top:])
        n_lanes = env.unwrapped.scenario.road.n_lanes
        assert len(groups) == n_lanes + 1 and groups[0][2] == 1.0 and groups[-1][2] == 1.0
        # the HUD shows what the step's info and observation hold
        assert hud.q == info["q"] and hud.v == pytest.approx(float(obs[0]), rel=1e-6, abs=1e-5)
        assert hud.set_speed == pytest.approx(float(obs[5]), rel=1e-6)
        if math.isfinite(info["q"]):
            assert hud.gap == pytest.approx(info["gap_safe"] + info["q"], rel=1e-9, abs=1e-9)
            assert np.any(is_colour(frame[top:], GAP))  # the gap to the lead is drawn
        else:
            assert hud.gap == math.inf and not np.any(is_colour(frame[top:], GAP))
        assert hud.caption == info["scenario"] and hud.t == pytest.approx(info["t"])
        lead = int(core.world.neighbours.lead[0, 0])  # slot 1 or 2 (info["modes"]: theirs), -1 none
        assert hud.lead_mode == (int(info["modes"][lead - 1]) if lead >= 1 else None)
    finally:
        env.close()


def test_a_cut_in_vehicle_appears_in_the_egos_lane():
    env = gymnasium.make("acc_gym/SingleLane-v1", render_mode="rgb_array")
    env.reset(seed=0, options={"scenario": "singlelane/2/cut-in"})
    core = env.unwrapped.core
    w = core.world
    road = env.unwrapped.scenario.road
    top = hud_rows(batch_hud(core))
    scene_px = H - top
    margin = scene_px // 10
    sy = (scene_px - 2 * margin) / (road.n_lanes * road.lane_width)

    def lane_rows(y):  # the scene's rows of the lane centred on y
        r = margin + ((road.n_lanes - 0.5) * road.lane_width - y) * sy
        half = 0.5 * road.lane_width * sy  # [px]
        return slice(top + int(round(r - half)) + 2, top + int(round(r + half)) - 1)  # inside its lane lines

    def cut_in_pixels(frame, info):
        colour = mode_colour(int(info["modes"][0]) if info else -1)
        x0 = w.x[0, 0]
        cols = slice(max(int(round(col(w.x[0, 1] - L, x0))), 0), int(round(col(w.x[0, 1], x0))))
        return int(np.count_nonzero(is_colour(frame[lane_rows(w.y[0, 0]), cols], colour)))

    y_ego, y_cut = w.y[0, 0], w.y[0, 1]
    assert abs(y_cut - y_ego) == pytest.approx(road.lane_width)  # it starts a lane over
    frame = env.render()
    assert cut_in_pixels(frame, {}) == 0 and not np.any(is_colour(frame[top:], GAP))
    info = {}
    for _ in range(45):
        *_, info = env.step(np.array([0.0], np.float32))
    assert w.y[0, 1] == pytest.approx(y_ego) and w.neighbours.lead[0, 0] == 1  # it has cut in
    frame = env.render()
    assert cut_in_pixels(frame, info) > 100  # its body in the ego's lane
    line = np.flatnonzero(is_colour(frame[top + int(round(margin + ((road.n_lanes - 0.5) * road.lane_width
                                                                    - y_ego) * sy))], GAP))
    assert line.size and abs(line.max() + 2 - col(w.x[0, 1] - L, w.x[0, 0])) <= 1.5  # the gap now ends at it
    env.close()


def mode_colour(mode):
    return NO_MODE if mode < 0 else MODE_COLOURS[mode]


# ---------------------------------------------------------------------------------------------- viewer
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


def test_outline_colour_frames_every_body():
    frame = scene([100.0, 140.0], y=[0.0, 3.75], modes=[-1, 0])
    r = int(round(row(0.0)))
    cols = np.flatnonzero(is_colour(frame[r], OUTLINE))
    assert cols.size >= 2 and cols.min() == round(col(100.0 - L, 100.0))

"""What a reviewer sees in the videos: coverage on the ground, the trail, the landing kerbs, the
enlarged airframe, the chase camera's smoothing and the HUD — and that none of it changes the
flight. GL tests skip where no offscreen GL works."""

import math

import mujoco
import numpy as np
import pytest

from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.view.airframe import Airframe
from cpp_mujoco.physics.view.chase import ChaseRig, MissionDecor
from cpp_mujoco.physics.view.scenery import KERB_HALF_WIDTH, Scenery, landing_kerbs
from cpp_mujoco.physics.view.trail import Trail
from cpp_mujoco.review.hud import Hud, HudState, hud_lines, view_up_heading, wind_heading

SMALL = GridMap.from_ascii(["LL.TT", "LL.TT", "....."], name="small")


class _Script:
    """A policy flying a fixed list of actions (then landing)."""

    name = "script"

    def __init__(self, actions):
        self.actions, self.i = list(actions), 0

    def act(self, obs):
        action = self.actions[self.i] if self.i < len(self.actions) else 4
        self.i += 1
        return np.array([action])


def _project(model, data, camera: str, points, width: int, height: int) -> np.ndarray:
    """(N, 2) pixel (col, row) of world points in a named MJCF camera's image."""
    cam = model.camera(camera).id
    pos, mat = data.cam_xpos[cam], data.cam_xmat[cam].reshape(3, 3)
    v = (np.asarray(points, float) - pos) @ mat  # camera frame: x right, y up, looking along -z
    f = height / 2 / math.tan(math.radians(model.cam_fovy[cam]) / 2)
    return np.column_stack(
        [width / 2 + f * v[:, 0] / -v[:, 2], height / 2 - f * v[:, 1] / -v[:, 2]]
    )


def _ground_point(model, data, camera: str, col, row, width: int, height: int, z: float):
    """World (x, y) where pixels' rays meet the plane at height ``z``."""
    cam = model.camera(camera).id
    pos, mat = data.cam_xpos[cam], data.cam_xmat[cam].reshape(3, 3)
    f = height / 2 / math.tan(math.radians(model.cam_fovy[cam]) / 2)
    rays = np.column_stack([(col - width / 2) / f, (height / 2 - row) / f, -np.ones(len(col))])
    world = rays @ mat.T
    t = (z - pos[2]) / world[:, 2]
    return pos[:2] + t[:, None] * world[:, :2]


# ----------------------------------------------------------------------------- without GL
def test_landing_kerbs_outline_each_landing_area_in_few_boxes():
    geo = GridGeometry.of(SMALL, 4.0)
    pos, size = landing_kerbs(SMALL.landing, geo)
    assert len(pos) == 4  # one 2×2 block: four straight sides, not 16 cell edges
    hx, hy = geo.half_extent
    x0, y1 = -hx, hy  # the block is the top-left 2×2 cells: x ∈ [-10, -2], y ∈ [2, 6]
    sides = {tuple(np.round(p[:2], 6)) for p in pos}
    assert sides == {(x0 + 4, y1), (x0 + 4, y1 - 8), (x0, y1 - 4), (x0 + 8, y1 - 4)}
    long_sides = np.sort(size[:, :2].max(axis=1))
    assert np.allclose(long_sides, 4 + KERB_HALF_WIDTH)  # each spans two cells, corners closed
    two = GridMap.from_ascii(["LTL", "TTT", "LLL"], name="two")  # three separate areas
    assert len(landing_kerbs(two.landing, GridGeometry.of(two, 4.0))[0]) == 4 + 4 + 4
    assert Scenery(SMALL, PhysicsConfig()).geom_count == 15 + 4 + 0


def test_trail_keeps_the_whole_route_coarser_and_restarts_on_reset():
    trail = Trail(spacing=0.5, max_points=10)
    for i in range(100):
        trail.update((0.3 * i, 0.0, 6.0), time=0.1 * i)
    assert len(trail.points) <= 10
    assert trail.points[0][0] == 0.0 and trail.head[0] == pytest.approx(29.7)  # start to now
    scene = mujoco.MjvScene(mujoco.MjModel.from_xml_string("<mujoco/>"), 50)
    trail.decorate(scene)
    assert 2 <= scene.ngeom <= trail.geom_count
    assert all(scene.geoms[i].type == mujoco.mjtGeom.mjGEOM_LINE for i in range(scene.ngeom))
    trail.update((5.0, 5.0, 6.0), time=0.0)  # an earlier time: a new episode
    assert len(trail.points) == 1
    scene.ngeom = 49
    trail.update((9.0, 5.0, 6.0), time=1.0)
    trail.decorate(scene)  # one slot left: drawn in part, never an error
    assert scene.ngeom == 50


def test_airframe_is_enlarged_about_the_skids_and_discs_glow_with_thrust():
    model = compile_arena(build_arena(SMALL, PhysicsConfig()))
    data = mujoco.MjData(model)
    data.qpos[:3] = (1.0, 2.0, 6.0)
    mujoco.mj_forward(model, data)
    airframe = Airframe(model, scale=3.0)
    pos, _ = airframe.pose(data)
    span = pos[:, :2].max(0) - pos[:, :2].min(0)
    assert span.min() > 3 * 2 * 0.159 * 0.9  # three times the real rotor spacing
    assert pos[:, 2].min() > 6.0 - 0.2  # scaled about the skids: nothing sinks below them

    def disc_brightness(act: float) -> float:
        data.act[:] = act
        scene = mujoco.MjvScene(model, 100)
        airframe.decorate(scene, data)
        discs = [scene.geoms[i].rgba for i in range(scene.ngeom)][-4:]
        return float(np.mean([d[:3].sum() for d in discs]))

    assert disc_brightness(3.7) > disc_brightness(0.0) + 0.5  # hovering vs motors off


def test_chase_rig_smooths_the_view_and_turns_to_the_direction_of_flight():
    rig = ChaseRig(tau_lookat=0.5, tau_heading=1.0, max_turn=90.0, azimuth=90.0)
    rig.update((0.0, 0.0, 6.0), 0.0)
    assert np.allclose(rig.lookat, (0, 0, 6)) and rig.azimuth == 90.0  # snaps at the start
    for k in range(1, 6):  # flying east at 2 m/s, 10 frames/s
        rig.update((0.2 * k, 0.0, 6.0), 0.1 * k)
    assert 0 < rig.lookat[0] < 1.0  # lags behind (smoothed), never jumps
    assert 45 < rig.azimuth < 90  # turning towards east (0°), at most 90°/s
    for k in range(6, 60):
        rig.update((0.2 * k, 0.0, 6.0), 0.1 * k)
    assert abs(rig.azimuth) < 2 or abs(rig.azimuth - 360) < 2  # now looking east
    assert rig.lookat[0] > 0.2 * 59  # ahead of the UAV: the next cells are in view
    rig.overview = (np.array([1.0, 2.0, 0.0]), 80.0, -65.0, 90.0)  # the end: the whole map
    rig.pull = 1.0
    lookat, distance, elevation, azimuth = rig.pose()
    assert np.allclose(lookat, (1, 2, 0)) and (distance, elevation) == (80.0, -65.0)
    assert azimuth == pytest.approx(90.0) and rig.heading == pytest.approx(90.0)
    rig.pull = 0.5
    assert rig.pose()[1] == pytest.approx((rig.distance + 80.0) / 2)  # halfway, eased
    rig.update((0.0, 0.0, 6.0), 0.0)  # a reset
    assert rig.azimuth == 90.0 and np.allclose(rig.lookat, (0, 0, 6)) and rig.pull == 0.0
    once = ChaseRig()  # env.render(): one frame per action, 3 s apart, converges in one
    once.update((0.0, 0.0, 6.0), 0.0)
    once.update((4.0, 0.0, 6.0), 3.0)
    assert once.lookat[0] == pytest.approx(4.0 + 4.0 / 3.0 * (1 - math.exp(-3)), abs=0.05)


def test_hud_lines_say_the_state():
    state = HudState(
        map_name="A", policy="ddqn-A", time_s=42.25, budget_left=37.44, budget_start=50,
        energy_used_j=12345.0, state_of_charge=0.781, coverage=0.434, action="east",
        wind_speed=5.0, wind_heading=-90.0,
    )  # fmt: skip
    assert hud_lines(state) == [
        "map A · ddqn-A",
        "t   42.2 s   east",
        "budget  37.4 / 50 u",
        "energy  12.3 kJ  SoC  78%",
        "coverage  43%",
    ]
    assert wind_heading(PhysicsConfig(wind_speed=5, wind_direction=90).wind_vector) == (
        pytest.approx(180.0)  # from the east: blowing west
    )
    down = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], float)  # image up = world +x
    assert view_up_heading(down) == pytest.approx(0.0)


def test_hud_state_reads_the_env_as_its_info_does():
    from cpp_mujoco.physics.envs.single import MuJoCoEnv
    from cpp_mujoco.review.flight_review import hud_state

    env = MuJoCoEnv(map=SMALL, wind_speed=3.0, wind_direction=0.0)
    env.reset(seed=0, options={"start": (0, 1), "budget": 10})
    *_, info = env.step(1)
    state = hud_state(env, map_name="small", policy="p", budget=10, action=1, view_up=90.0)
    assert math.floor(state.budget_left + 1e-9) == info["budget"]
    assert state.energy_used_j == info["energy_used_j"]
    assert state.state_of_charge == info["state_of_charge"]
    assert state.coverage == pytest.approx(info["coverage_ratio"])
    assert state.action == "east" and state.time_s == info["flight_time_s"]
    assert state.wind_speed == 3.0 and state.wind_heading == pytest.approx(270.0)  # to the south


def test_hud_draws_its_text_in_its_boxes_and_nowhere_else():
    hud = Hud(512, 384)
    frame = np.random.default_rng(0).integers(60, 200, (384, 512, 3), dtype=np.uint8)
    kept = frame.copy()
    state = HudState("A", "ddqn-A", 1.0, 50.0, 50, 0.0, 1.0, 0.0, "north", 5.0, 90.0, 90.0)
    drawn = hud.draw(frame, state)
    assert drawn.shape == frame.shape and drawn.dtype == np.uint8
    assert np.array_equal(frame, kept)  # drawn on a copy
    changed = np.any(drawn != frame, axis=2)
    inside = np.zeros_like(changed)
    boxes = [hud.panel_box(hud_lines(state)), hud.wind_box()]
    for x0, y0, x1, y1 in boxes:
        inside[y0:y1, x0:x1] = True
    assert not changed[~inside].any() and changed[inside].mean() > 0.9  # darkened
    x0, y0, x1, y1 = boxes[0]
    panel = drawn[y0:y1, x0:x1].astype(int)
    assert (panel.min(axis=2) > 200).sum() > 300  # white text on the dark panel
    # another state, other text: the panel differs; the outcome banner appears at the bottom
    other = hud.draw(frame, HudState("A", "ddqn-A", 99.0, 3.0, 50, 2e4, 0.2, 0.9, "land",
                                     5.0, 90.0, 90.0, status="landed · coverage 90%"))  # fmt: skip
    assert np.any(other[y0:y1, x0:x1] != drawn[y0:y1, x0:x1])
    bx0, by0, bx1, by1 = hud.banner_box("landed · coverage 90%")
    assert by1 > 340 and np.any(other[by0:by1, bx0:bx1] != frame[by0:by1, bx0:bx1])


def test_wind_arrow_points_the_way_the_wind_blows_in_the_picture():
    hud = Hud(512, 384)
    frame = np.zeros((384, 512, 3), dtype=np.uint8)
    cx, cy, r = hud.compass()

    def arrow_centroid(wind_to: float, view_up: float) -> np.ndarray:
        state = HudState("A", "p", 0.0, 1.0, 1, 0.0, 1.0, 0.0, None, 4.0, wind_to, view_up)
        out = hud.draw(frame, state).astype(int)
        yellow = (out[..., 0] > 150) & (out[..., 2] < 120)  # the accent colour
        rows, cols = np.nonzero(yellow)
        return np.array([cols.mean() - cx, rows.mean() - cy])  # head-heavy: towards the tip

    up = arrow_centroid(wind_to=90.0, view_up=90.0)  # blowing north, north up
    assert up[1] < -1 and abs(up[0]) < 1.5
    left = arrow_centroid(wind_to=180.0, view_up=90.0)  # blowing west: to the left
    assert left[0] < -1 and abs(left[1]) < 1.5
    turned = arrow_centroid(wind_to=180.0, view_up=180.0)  # looking west: it blows away, up
    assert turned[1] < -1 and abs(turned[0]) < 1.5


# ----------------------------------------------------------------------------- with GL
def test_covered_cells_turn_lighter_and_nothing_else_changes(gl):
    """A frame late in a mission against the first, seen by the arena's fixed overview camera
    (the chase camera moves): exactly the pixels of cells covered in between changed, lighter."""
    from cpp_mujoco.physics.envs.single import MuJoCoEnv
    from cpp_mujoco.physics.view.rendering import OffscreenCamera

    env = MuJoCoEnv(map="A")
    env.reset(seed=0, options={"start": (13, 0), "budget": 50})
    w, h = 512, 384
    decor = MissionDecor(env.model, Scenery(env.grid_map, env.config), env.mdp.coverage)
    camera = OffscreenCamera(env.model, camera="overview", width=w, height=h, decorate=decor)
    camera.scene_option.geomgroup[2] = 0  # the UAV itself moves between the frames
    seen_first = env.mdp.coverage[0].copy()
    first = camera.render(env.data).astype(int)
    for action in (0, 0, 1, 1):  # north, north, east, east
        env.step(action)
    late = camera.render(env.data).astype(int)
    camera.close()
    newly = env.mdp.coverage[0] & ~seen_first
    assert newly.sum() >= 6
    geo = GridGeometry.of(env.grid_map, env.config.cell_size)
    centres = np.column_stack([geo.centers(), np.full(geo.height * geo.width, 0.01)])
    pixels = np.round(_project(env.model, env.data, "overview", centres, w, h)).astype(int)
    for cell, (c, r) in enumerate(pixels):
        if not (2 <= c < w - 2 and 2 <= r < h - 2):
            continue
        a, b = first[r - 1 : r + 2, c - 1 : c + 2], late[r - 1 : r + 2, c - 1 : c + 2]
        if newly[cell]:
            assert b.sum() > a.sum() + 9 * 3 * 10, cell  # lighter
        else:
            assert np.array_equal(a, b), cell  # untouched
    rows, cols = np.nonzero(np.any(first != late, axis=2))
    xy = _ground_point(env.model, env.data, "overview", cols, rows, w, h, 0.01)
    covered = geo.centers()[newly]
    nearest = np.abs(xy[:, None, :] - covered[None, :, :]).max(axis=2).min(axis=1)
    assert nearest.max() < env.config.cell_size / 2 + 0.3  # every changed pixel: a covered cell


def test_the_airframe_is_drawn_large_where_the_uav_is(gl):
    from cpp_mujoco.physics.envs.single import MuJoCoEnv
    from cpp_mujoco.physics.view.chase import chase_camera

    env = MuJoCoEnv(map="A")
    env.reset(seed=0, options={"start": (13, 0), "budget": 50})
    frames = {}
    for drawn in (True, False):
        camera = chase_camera(env.model, 512, 384, airframe=drawn)
        camera.scene_option.geomgroup[2] = 0  # without: the bare ground
        frames[drawn] = camera.render(env.data).astype(int)
        camera.close()
    changed = np.any(np.abs(frames[True] - frames[False]) > 30, axis=2)
    rows, cols = np.nonzero(changed)
    # the first frame looks at the UAV: it is at the frame's centre, and only there
    assert abs(np.median(rows) - 192) < 25 and abs(np.median(cols) - 256) < 25
    assert changed.sum() > 500 and np.ptp(cols) > 35  # clearly visible: ~50 px across
    assert np.abs(rows - 192).max() < 80 and np.abs(cols - 256).max() < 80


def test_rendering_leaves_the_flight_unchanged(gl, tmp_path):
    """Fly the same actions with every camera rendering every frame (and ``render()`` every
    step) and with none: same states, same energies, same infos."""
    from cpp_mujoco.physics.envs.single import MuJoCoEnv
    from cpp_mujoco.review.flight_review import FlightReview

    runs = []
    for rendering in (False, True):
        env = MuJoCoEnv(map=SMALL, wind_speed=4.0, turbulence="light", render_mode="rgb_array")
        env.reset(seed=3, options={"start": (0, 1), "budget": 12})
        frames = []
        if rendering:
            cameras, writers = [], []
            review = FlightReview(env, None, None, tmp_path / "onboard.mp4", 2, cameras, writers,
                                  about={"map_name": "small", "policy": "p", "budget": 12},
                                  on_chase_frame=frames.append)  # fmt: skip
            env.on_frame = review.on_frame
        trace = []
        for action in (1, 2, 3, 4):  # east, two turns back into the landing area, land
            *_, info = env.step(action)
            if rendering:
                assert env.render().shape == (384, 512, 3)
            trace.append((env.data.qpos.copy(), env.data.qvel.copy(), env.data.act.copy(), info))
        if rendering:
            assert len(frames) > 50 and info["landed"]
            for camera in cameras:
                camera.close()
            assert writers[0][1].close() is not None  # the onboard video got every frame
        env.close()
        runs.append(trace)
    for (q0, v0, a0, i0), (q1, v1, a1, i1) in zip(*runs, strict=True):
        assert np.array_equal(q0, q1) and np.array_equal(v0, v1) and np.array_equal(a0, a1)
        assert i0 == i1


def test_a_mission_ends_its_video_on_the_outcome(gl, tmp_path):
    import imageio.v3 as iio

    from cpp_mujoco.missions.mission import fly_mission
    from cpp_mujoco.review.flight_review import HOLD_S, outcome_status

    frames = []
    outcome = fly_mission(_Script([1, 3]), SMALL, budget=10, start=(0, 1),
                          video=tmp_path / "chase.mp4", onboard_video=tmp_path / "onboard.mp4",
                          on_chase_frame=frames.append)  # fmt: skip
    assert outcome.landed
    video = iio.imread(tmp_path / "chase.mp4")
    hold = round(HOLD_S * PhysicsConfig().camera_rate)
    assert len(video) == len(frames) - 1 + hold  # the last frame given once, held in the video
    status = outcome_status({"landed": True, "coverage_ratio": outcome.coverage_ratio})
    x0, y0, x1, y1 = Hud(512, 384).banner_box(status)
    banner = frames[-1][y0:y1, x0:x1].astype(int)
    assert ((banner[..., 0] > 150) & (banner[..., 2] < 120)).sum() > 50  # the outcome, in yellow
    # the end pulls back over the whole map: the landing area fills less of the frame
    blue = [((f[..., 2] > 150) & (f[..., 0] < 100)).mean() for f in (frames[-2], frames[-1])]
    assert blue[1] < blue[0]
    assert len(iio.imread(tmp_path / "onboard.mp4")) == len(video)

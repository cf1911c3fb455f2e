"""The map's tiles and no-fly volumes as render-time scenery: where and in what colour they are
drawn, and that rendered frames still show them although the physics model no longer holds them."""

import mujoco
import numpy as np
import pytest

from cpp_mujoco.maps import GridMap, load_map
from cpp_mujoco.physics.arena import build_arena, compile_arena
from cpp_mujoco.physics.config import PhysicsConfig
from cpp_mujoco.physics.geometry import GridGeometry
from cpp_mujoco.physics.view.scenery import (
    NFZ_VOLUME_RGBA,
    TILE_GAP,
    ZONE_RGBA,
    Scenery,
    SceneryError,
    zone_of,
)

ODD = GridMap.from_ascii(["LTN.", "GY.T", "TTTT"], name="odd")  # every zone, not square
CONFIG = PhysicsConfig(cell_size=3.0, altitude=4.5)


@pytest.fixture(scope="module")
def model():
    return compile_arena(build_arena(ODD, CONFIG))


def test_tiles_sit_on_the_cell_centres_in_their_zone_colours():
    scenery = Scenery(ODD, CONFIG)
    geo = GridGeometry.of(ODD, CONFIG.cell_size)
    pos, size, rgba = scenery.tiles()
    assert size.tolist() == pytest.approx([1.5 - TILE_GAP / 2, 1.5 - TILE_GAP / 2, 0.005])
    for cell, (x, y, z) in enumerate(pos):
        row, col = divmod(cell, geo.width)
        assert (x, y) == geo.cell_center(row, col) and z == size[2]  # lying on the ground
        assert rgba[cell].tolist() == pytest.approx(ZONE_RGBA[zone_of(ODD, row, col)])
    assert zone_of(ODD, 1, 0) == "landing_target" and zone_of(ODD, 1, 1) == "target_nfz"
    volumes, half, colour = scenery.volumes()
    nfz = [geo.cell_center(r, c) for r, c in np.argwhere(ODD.nfz)]
    assert volumes[:, :2].tolist() == [list(xy) for xy in nfz]
    assert half.tolist() == [1.5, 1.5, CONFIG.altitude] and volumes[:, 2].tolist() == [4.5, 4.5]
    assert colour.tolist() == pytest.approx(NFZ_VOLUME_RGBA)
    assert scenery.geom_count == ODD.landing.size + 4 + 2  # tiles, the landing kerbs, volumes


def test_the_model_carries_its_map(model):
    """``chase_camera(model)`` (what ``MuJoCo-v0.render()`` calls) draws the map from the model."""
    ours, stored = Scenery(ODD, CONFIG), Scenery.from_model(model)
    for a, b in zip(ours.tiles() + ours.volumes(), stored.tiles() + stored.volumes(), strict=True):
        assert np.array_equal(a, b)
    bare = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    assert Scenery.from_model(bare) is None


def test_decorate_appends_after_the_model_geoms(model):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    scene = mujoco.MjvScene(model, 40)
    option, camera = mujoco.MjvOption(), mujoco.MjvCamera()
    mujoco.mjv_updateScene(
        model, data, option, None, camera, mujoco.mjtCatBit.mjCAT_ALL, scene
    )  # fmt: skip
    before = scene.ngeom
    scenery = Scenery.from_model(model)
    assert before + scenery.geom_count <= 40 < before + 2 * scenery.geom_count
    seen = np.zeros(ODD.shape, dtype=bool)
    seen[0, 1] = True  # a target cell the camera saw
    scenery.decorate(scene, seen)
    assert scene.ngeom == before + scenery.geom_count
    tiles = [scene.geoms[before + i] for i in range(ODD.landing.size)]
    pos, size, rgba = scenery.tiles()
    for cell, (geom, p, c) in enumerate(zip(tiles, pos, rgba, strict=True)):
        assert geom.type == mujoco.mjtGeom.mjGEOM_BOX and np.allclose(geom.pos, p)
        assert np.allclose(geom.size, size)
        assert cell == 1 or np.allclose(geom.rgba, c)  # unseen: the zone's colour
    lighter = tiles[1].rgba
    assert np.all(lighter[:3] > rgba[1][:3]) and lighter[3] == 1.0  # seen: lighter, opaque
    volume = scene.geoms[scene.ngeom - 1]
    assert np.allclose(volume.rgba, NFZ_VOLUME_RGBA) and volume.pos[2] == pytest.approx(4.5)
    with pytest.raises(ValueError, match="seen has 3 cells"):
        scenery.decorate(scene, np.ones(3, dtype=bool))
    full = scene.ngeom
    with pytest.raises(SceneryError, match="max_geom"):
        scenery.decorate(scene)  # no room for a second copy
    assert scene.ngeom == full  # nothing half drawn


def test_frames_show_the_tiles_and_the_chase_camera_draws_them_by_default(gl):
    from cpp_mujoco.physics.view.chase import chase_camera
    from cpp_mujoco.physics.view.rendering import OffscreenCamera

    grid_map, config = load_map("A"), PhysicsConfig()
    model = compile_arena(build_arena(grid_map, config))
    data = mujoco.MjData(model)
    row, col = (int(v) for v in np.argwhere(grid_map.landing)[0])
    x, y = GridGeometry.of(grid_map, config.cell_size).cell_center(row, col)
    data.qpos[:3] = (x, y, config.altitude)  # over a landing cell, looking down
    mujoco.mj_forward(model, data)
    scenery = Scenery(grid_map, config)
    frames = {}
    for name, decorate in (("bare", None), ("scenery", scenery)):
        camera = OffscreenCamera(model, camera="quadrotor/downward", decorate=decorate)
        frames[name] = camera.render(data).astype(int)
        camera.close()
    h, w, _ = frames["scenery"].shape
    middle = (slice(h // 2 - 30, h // 2 + 30), slice(w // 2 - 30, w // 2 + 30))
    r, g, b = frames["scenery"][middle].reshape(-1, 3).mean(0)  # the landing tile under the UAV
    assert b >= g > r + 40, (r, g, b)  # landing blue (lit brightly), not the grey ground
    r, g, b = frames["bare"][middle].reshape(-1, 3).mean(0)
    assert max(r, g, b) - min(r, g, b) < 10, (r, g, b)  # the bare ground plane is grey
    assert np.abs(frames["scenery"] - frames["bare"]).mean() > 30
    chased = []
    for kwargs in ({}, {"scenery": scenery}):  # {}: MuJoCo-v0.render()'s call
        camera = chase_camera(model, 160, 120, **kwargs)
        chased.append(camera.render(data))
        camera.close()
    assert np.array_equal(*chased)

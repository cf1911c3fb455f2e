"""``cpp-mujoco site``: a real site's polygons to a grid (cell by cell), a battery to a budget
(against the physics' calibration), a policy's route to a QGroundControl plan and a MAVLink
waypoint file that pymavlink reads back and MuJoCo flies again; every bad input is one line
naming the feature, with nothing written."""

import copy
import json
import math
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest

pytest.importorskip("shapely", reason="the site extra is not installed (pip install -e .[site])")
pytest.importorskip("pyproj", reason="the site extra is not installed")
pytest.importorskip("pymavlink", reason="the site extra is not installed")

from pymavlink import mavwp  # noqa: E402
from pyproj import Geod, Transformer  # noqa: E402

from cpp_mujoco.cli.main import build_parser, main  # noqa: E402
from cpp_mujoco.physics.calibration import calibration, unit_energy  # noqa: E402
from cpp_mujoco.physics.config import PhysicsConfig  # noqa: E402
from cpp_mujoco.physics.quadrotor import QuadrotorParams, quadrotor_xml  # noqa: E402
from cpp_mujoco.sites.budget import (  # noqa: E402
    Battery,
    FlightSettings,
    budget_of,
    physics_config,
)
from cpp_mujoco.sites.checks import Limits, cells_of_items  # noqa: E402
from cpp_mujoco.sites.export import read_waypoints  # noqa: E402
from cpp_mujoco.sites.geojson import SiteError, read_site, site_from_features  # noqa: E402
from cpp_mujoco.sites.raster import (  # noqa: E402
    Georeference,
    RasterConfig,
    rasterise,
    true_north_in_crs,
    utm_crs,
)
from cpp_mujoco.sites.route import ActionReplay, actions_between, fly_episode  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "farm_site.geojson"
EXAMPLE_HEADING = "15"


# ----------------------------------------------------------------------------- helpers
def _site_in_metres(features, lon0=-93.6, lat0=42.0, heading=0.0, cell=4.0):
    """GeoJSON-like (properties, geometry) pairs from polygons drawn in a grid's local frame
    (x east along the rows, y up, origin the north-west corner) placed at (lon0, lat0)."""
    crs = utm_crs(lon0, lat0)
    east, north = Transformer.from_crs("EPSG:4326", crs, always_xy=True).transform(lon0, lat0)
    rotation = heading + true_north_in_crs(crs, lon0, lat0)
    g = Georeference(crs, lon0, lat0, east, north, cell, heading, rotation, 0, 0)
    back = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)
    raw = []
    for kind, name, corners in features:
        xs, ys = zip(*corners, strict=True)
        lons, lats = back.transform(*g.to_projected(list(xs), list(ys)))
        ring = [[float(a), float(b)] for a, b in zip(lons, lats, strict=True)]
        raw.append(({"kind": kind, "name": name}, {"type": "Polygon",
                                                   "coordinates": [ring + ring[:1]]}))  # fmt: skip
    return raw


def _box(x0, y0, x1, y1):
    return [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]


def _write(tmp_path: Path, data: dict, name: str = "site.geojson") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def _example() -> dict:
    return json.loads(EXAMPLE.read_text())


def _feature(data: dict, name: str) -> dict:
    return next(f for f in data["features"] if f["properties"]["name"] == name)


# ----------------------------------------------------------------------------- rasterising
def test_a_site_rasterises_cell_by_cell():
    # 10 x 8 cells of 4 m: x 0..40 east, y 0..-32 south; each rule at its edge
    features = [
        ("boundary", "parcel", [(0, 0), (30, 0), (30, -8), (40, -8), (40, -32), (0, -32)]),
        ("target", "full", _box(4, -12, 20, -4)),  # rows 1-2, cols 1-4 wholly
        ("target", "52%", _box(28, -24, 30.08, -20)),  # (5, 7): 52 % covered -> target
        ("target", "48%", _box(32, -24, 33.92, -20)),  # (5, 8): 48 % -> not
        ("no-fly", "mast", _box(9.9, -25.9, 10.1, -25.7)),  # a speck inside (6, 2)
        ("no-fly", "shed", _box(16.5, -31.5, 20.01, -28.5)),  # (7, 4), 1 cm into (7, 5)
        ("obstacle", "tree", _box(17, -11, 18, -10)),  # inside target cell (2, 4)
        ("landing", "pad", _box(0, -32, 8, -28)),  # (7, 0), (7, 1)
    ]
    site = site_from_features(_site_in_metres(features), "cells", "test")
    grid_map, local = rasterise(site, RasterConfig(cell_size=4.0, nfz_margin=1.0))
    assert grid_map.shape == (8, 10) and (local.georef.rows, local.georef.cols) == (8, 10)
    target = np.zeros((8, 10), bool)
    target[1:3, 1:5] = True
    target[2, 4] = False  # under the tree: an obstacle cell is not a target
    target[5, 7] = True
    nfz = np.zeros((8, 10), bool)
    nfz[0:2, 7:10] = True  # outside the boundary's notch, (x 30..40, y 0..-8), in part or whole
    nfz[6, 2] = nfz[7, 4] = nfz[7, 5] = True
    obstacle = np.zeros((8, 10), bool)
    obstacle[2, 4] = True
    landing = np.zeros((8, 10), bool)
    landing[7, 0:2] = True
    for layer, want in (("target", target), ("nfz", nfz), ("obstacle", obstacle),
                        ("landing", landing)):  # fmt: skip
        got = getattr(grid_map, layer)
        assert np.array_equal(got, want), (layer, np.argwhere(got != want).tolist())


def test_the_no_fly_margin_beyond_half_a_cell_grows_the_no_fly_cells():
    features = [
        ("boundary", "parcel", _box(0, -32, 40, 0)),
        ("target", "field", _box(20, -16, 40, 0)),
        ("no-fly", "hut", _box(9.5, -17.5, 10.5, -14.5)),  # in col 2, 1.5 m from 1 and 3
        ("landing", "pad", _box(0, -32, 8, -28)),
    ]
    site = site_from_features(_site_in_metres(features), "margin", "test")
    tight, _ = rasterise(site, RasterConfig(nfz_margin=1.5))  # under half a cell: not grown
    wide, _ = rasterise(site, RasterConfig(nfz_margin=4.0))  # grown by 2 m: into cols 1 and 3
    assert np.argwhere(tight.nfz).tolist() == [[3, 2], [4, 2]]
    assert np.argwhere(wide.nfz).tolist() == [[3, 1], [3, 2], [3, 3], [4, 1], [4, 2], [4, 3]]


@pytest.mark.parametrize(
    ("lon", "lat", "heading", "cell"),
    [(-93.5846, 42.0129, 15.0, 4.0), (149.13, -35.28, 237.5, 2.5), (2.9, 64.5, 0.0, 10.0)],
)
def test_cell_centres_round_trip_through_wgs84_within_a_centimetre(lon, lat, heading, cell):
    features = [("target", "field", _box(0, -60, 80, 0)), ("landing", "pad", _box(0, -60, 8, -52))]
    site = site_from_features(_site_in_metres(features, lon, lat, heading, cell), "rt", "test")
    _, local = rasterise(site, RasterConfig(cell_size=cell, heading=heading))
    g = local.georef
    rows, cols = np.divmod(np.arange(g.rows * g.cols), g.cols)
    lons, lats = g.cell_centres_lonlat(rows, cols)
    back_rows, back_cols = g.lonlat_to_cells(lons, lats)
    error_m = np.hypot(back_rows - rows, back_cols - cols) * cell
    assert error_m.max() < 0.01
    # on the ellipsoid: neighbours one cell apart, rows pointing at the heading (true north)
    geod = Geod(ellps="WGS84")
    i, right, up = 0 * g.cols + 0, 0 * g.cols + 1, 1 * g.cols + 0  # (0,0), (0,1), (1,0)
    _, _, across = geod.inv(lons[i], lats[i], lons[right], lats[right])
    azimuth, _, along = geod.inv(lons[up], lats[up], lons[i], lats[i])
    assert across == pytest.approx(cell, rel=1e-3) and along == pytest.approx(cell, rel=1e-3)
    assert (azimuth - heading + 180) % 360 - 180 == pytest.approx(0, abs=0.05)


# ----------------------------------------------------------------------------- the budget
def test_the_budget_is_the_pack_over_the_calibrated_move():
    config = physics_config(FlightSettings(), 4.0, heading=0.0)
    assert config.calibration_key() == PhysicsConfig().calibration_key()  # the default move
    battery = Battery(usable_wh=10.0, reserve=0.25, climb_speed=2.0)
    budget = budget_of(battery, config)
    unit = unit_energy(config)
    model = mujoco.MjModel.from_xml_path(str(quadrotor_xml()))
    weight = QuadrotorParams.from_model(model, prefix="").weight
    hover_w = calibration(config)["hover_power_w"]
    assert budget.takeoff_j == pytest.approx(hover_w * config.altitude / 2.0 + weight * 6.0)
    assert budget.unit_energy_j == unit
    assert budget.usable_j == 36000.0 and budget.reserve_j == 9000.0
    assert budget.units == math.floor((36000.0 - 9000.0 - budget.takeoff_j) / unit)
    assert budget.planned_j == budget.units * unit and 0 <= budget.margin_j < unit


def test_cell_size_and_speed_set_the_move_and_the_wind_turns_with_the_grid():
    flight = FlightSettings(altitude=7.5, cruise_speed=2.0, wind_speed=4, wind_direction=90)
    config = physics_config(flight, 5.0, heading=15.0)
    assert config.cell_size == 5.0 and config.altitude == 7.5
    assert config.move_duration == pytest.approx(1.875 * 5.0 / 2.0)
    assert config.wind_direction == pytest.approx(75.0)  # from the east, seen from a 15° grid
    calm = physics_config(FlightSettings(altitude=7.5, cruise_speed=2.0), 5.0, heading=15.0)
    assert unit_energy(calm) > unit_energy(PhysicsConfig())  # a longer, slower move: more J
    with pytest.raises(ValueError, match="holds 0 move"):
        budget_of(Battery(usable_wh=0.1), physics_config(FlightSettings(), 4.0, 0.0))


# ----------------------------------------------------------------------------- end to end
@pytest.fixture(scope="module")
def example_mission(tmp_path_factory):
    out = tmp_path_factory.mktemp("mission")
    code = main(["site", "plan", str(EXAMPLE), "--heading", EXAMPLE_HEADING, "--out", str(out)])
    assert code == 0
    return out


def test_the_example_site_is_planned_exported_and_flown(example_mission):
    report = json.loads((example_mission / "mission.json").read_text())
    assert set(report["files"].values()) == {p.name for p in example_mission.iterdir()}
    assert all(check["passed"] for check in report["checks"]) and len(report["checks"]) == 11
    route = report["route"]
    assert route["landed"] and route["coverage_ratio"] > 0.8 and route["policy"] == "beam-search"
    assert report["from_file"]["targets_seen"] == route["targets_seen"]
    budget = report["budget"]
    assert budget["units"] == route["budget"]
    spend = budget["usable_wh"] - budget["reserve_wh"]
    assert report["expected"]["energy_wh"] <= spend
    assert (example_mission / "map.png").stat().st_size > 100
    assert (example_mission / "route.png").stat().st_size > 20_000


def test_the_plan_is_a_qgroundcontrol_plan(example_mission):
    plan = json.loads((example_mission / "mission.plan").read_text())
    assert plan["fileType"] == "Plan" and plan["version"] == 1
    assert isinstance(plan["groundStation"], str)
    mission = plan["mission"]
    assert mission["version"] == 2 and mission["firmwareType"] == 12  # PX4
    assert mission["vehicleType"] == 2 and mission["cruiseSpeed"] == 2.5  # a quadrotor
    assert len(mission["plannedHomePosition"]) == 3
    items = mission["items"]
    commands = [i["command"] for i in items]
    assert commands[:2] == [22, 178] and commands[-1] == 21  # take-off, speed, ..., land
    assert set(commands[2:-1]) == {16}
    assert [i["doJumpId"] for i in items] == list(range(1, len(items) + 1))
    for item in items:
        assert item["type"] == "SimpleItem" and item["autoContinue"] is True
        assert len(item["params"]) == 7
        assert item["frame"] == (2 if item["command"] == 178 else 3)  # relative altitude
    flying = [i for i in items if i["command"] in (22, 16)]
    assert {i["params"][6] for i in flying} == {6.0} and {i["Altitude"] for i in flying} == {6.0}
    assert items[0]["params"][4:6] == mission["plannedHomePosition"][:2]
    fence = plan["geoFence"]
    assert fence["version"] == 2 and fence["circles"] == []
    assert sorted(p["inclusion"] for p in fence["polygons"]) == [False, False, True]
    assert all(p["version"] == 1 and len(p["polygon"]) >= 3 for p in fence["polygons"])
    rally = plan["rallyPoints"]
    assert rally["version"] == 2 and len(rally["points"]) == 1 and len(rally["points"][0]) == 3
    pad = _feature(_example(), "grass pad")["geometry"]["coordinates"][0]
    lons, lats = zip(*pad, strict=True)
    lat, lon, _ = rally["points"][0]
    assert min(lats) <= lat <= max(lats) and min(lons) <= lon <= max(lons)


def test_the_waypoint_file_read_back_flies_the_same_mission(example_mission):
    text = (example_mission / "mission.waypoints").read_text()
    assert text.startswith("QGC WPL 110\n")
    loader = mavwp.MAVWPLoader()
    loader.load(str(example_mission / "mission.waypoints"))
    plan = json.loads((example_mission / "mission.plan").read_text())
    assert loader.count() == len(plan["mission"]["items"]) + 1  # the home line first
    georef = Georeference.load(example_mission / "georef.json")
    cells = cells_of_items(read_waypoints(example_mission / "mission.waypoints"), georef)
    report = json.loads((example_mission / "mission.json").read_text())
    assert [list(c) for c in cells] == report["route"]["cells"]
    assert list(cells[0]) == report["route"]["start"]
    # flown again here, from the file's cells (the moves between them), not the policy's actions
    site = read_site(EXAMPLE)
    grid_map, _ = rasterise(site, RasterConfig(heading=float(EXAMPLE_HEADING)))
    config = physics_config(FlightSettings(), 4.0, float(EXAMPLE_HEADING))
    flown = fly_episode(ActionReplay(actions_between(cells)), grid_map, config,
                        budget=report["budget"]["units"], start=cells[0])  # fmt: skip
    assert flown.landed and flown.end == cells[-1] and grid_map.landing[flown.end]
    assert int(flown.seen.sum()) == report["route"]["targets_seen"]
    assert flown.coverage_ratio == pytest.approx(report["route"]["coverage_ratio"])


def test_a_failed_check_refuses_the_mission_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["site", "plan", str(EXAMPLE), "--heading", EXAMPLE_HEADING, "--out", str(out),
            "--battery-wh", "4", "--planner", "safe-greedy"]  # fmt: skip
    assert main([*argv, "--max-altitude", "5"]) == 2
    err = capsys.readouterr().err
    assert "mission refused" in err and "altitude within limits failed (6..6 m" in err
    assert not out.exists()


def test_an_agent_flies_a_site_and_is_refused_one_it_cannot_read(tmp_path, capsys):
    """The bundled general agent reads no obstacle layer: refused on the example (its
    windbreak), flown on the same site without it."""
    argv = ["site", "plan", "--heading", EXAMPLE_HEADING, "--agent", "general",
            "--battery-wh", "4"]  # fmt: skip
    refused = tmp_path / "refused"
    assert main([*argv, str(EXAMPLE), "--out", str(refused)]) == 2
    assert "reads no obstacle layer" in capsys.readouterr().err and not refused.exists()
    data = copy.deepcopy(_example())
    data["features"].remove(_feature(data, "windbreak"))
    flown = tmp_path / "flown"
    assert main([*argv, str(_write(tmp_path, data)), "--out", str(flown)]) == 0
    report = json.loads((flown / "mission.json").read_text())
    assert report["route"]["policy"].startswith("ddqn-general") and report["route"]["landed"]
    assert report["from_file"]["targets_seen"] == report["route"]["targets_seen"] > 0


# ----------------------------------------------------------------------------- bad input
def _empty(data):
    _feature(data, "test plot")["geometry"]["coordinates"] = [[[-93.585, 42.013]] * 4]


def _bow_tie(data):
    ring = _feature(data, "test plot")["geometry"]["coordinates"][0]
    ring[1], ring[2] = ring[2], ring[1]


def _swapped(data):
    ring = _feature(data, "windbreak")["geometry"]["coordinates"][0]
    ring[:] = [[lat, lon] for lon, lat in ring]


def _too_large(data):
    ring = _feature(data, "Hansen farm parcel")["geometry"]["coordinates"][0]
    ring[2][0] += 0.02  # 1.6 km further east: over 256 cells of 4 m


def _no_landing(data):
    data["features"].remove(_feature(data, "grass pad"))


def _landing_on_the_road(data):
    pad = _feature(data, "grass pad")["geometry"]["coordinates"][0]
    pad[:] = [[lon, lat - 0.00007] for lon, lat in pad]  # 8 m south: onto the road


@pytest.mark.parametrize(
    ("spoil", "message"),
    [
        (_empty, r"feature 2 \('test plot', target\) is an empty polygon"),
        (_bow_tie, r"feature 2 \('test plot', target\) is self-intersecting"),
        (
            _swapped,
            r"feature 3 \('windbreak', obstacle\): latitude -93.5\d+ is beyond ±90°: "
            r"its coordinates look swapped",
        ),
        (_too_large, r"the site spans \d+ m x \d+ m .* over the map limit of 256 cells"),
        (_no_landing, r"no landing polygon"),
        (
            _landing_on_the_road,
            r"feature 6 \('grass pad', landing\) overlaps feature 4 "
            r"\('county road', no-fly\)",
        ),
    ],
)
@pytest.mark.parametrize("command", ["plan", "grid"])
def test_bad_input_is_one_line_naming_the_feature_and_writes_nothing(
    tmp_path, capsys, spoil, message, command
):
    data = copy.deepcopy(_example())
    spoil(data)
    out = tmp_path / "out"
    assert main(["site", command, str(_write(tmp_path, data)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_kml_reads_as_the_same_site(tmp_path):
    data = _example()
    placemarks = []
    for f in data["features"]:
        coords = " ".join(f"{lon},{lat},0" for lon, lat in f["geometry"]["coordinates"][0])
        placemarks.append(
            f'<Placemark><name>{f["properties"]["name"]}</name><ExtendedData><Data name="kind">'
            f"<value>{f['properties']['kind']}</value></Data></ExtendedData><Polygon>"
            f"<outerBoundaryIs><LinearRing><coordinates>{coords}</coordinates></LinearRing>"
            f"</outerBoundaryIs></Polygon></Placemark>"
        )
    kml = tmp_path / "farm.kml"
    kml.write_text('<?xml version="1.0" encoding="UTF-8"?><kml xmlns="http://www.opengis.net/'
                   f'kml/2.2"><Document>{"".join(placemarks)}</Document></kml>')  # fmt: skip
    from_kml, from_json = read_site(kml), read_site(EXAMPLE)
    assert [(f.kind, f.name) for f in from_kml.features] == [
        (f.kind, f.name) for f in from_json.features
    ]
    assert all(a.geometry.equals(b.geometry) for a, b in
               zip(from_kml.features, from_json.features, strict=True))  # fmt: skip
    with pytest.raises(SiteError, match=r"feature 0 \('x'\) has no 'kind' property"):
        kml.write_text("<kml><Placemark><name>x</name><Polygon/></Placemark></kml>")
        read_site(kml)


def test_the_parser_names_the_configs_defaults():
    from cpp_mujoco.sites.budget import Battery, FlightSettings

    defaults = {
        "cell_size": RasterConfig().cell_size, "heading": RasterConfig().heading,
        "nfz_margin": RasterConfig().nfz_margin, "altitude": FlightSettings().altitude,
        "speed": FlightSettings().cruise_speed, "wind_speed": FlightSettings().wind_speed,
        "wind_direction": FlightSettings().wind_direction, "battery_wh": Battery().usable_wh,
        "reserve": Battery().reserve, "climb_speed": Battery().climb_speed,
        "min_altitude": Limits().min_altitude, "max_altitude": Limits().max_altitude,
    }  # fmt: skip
    site = build_parser(train_options=False)._subparsers._group_actions[0].choices["site"]  # noqa: SLF001
    plan = site._subparsers._group_actions[0].choices["plan"]  # noqa: SLF001
    named = {
        a.dest: float(re.search(r"\(default: ([\d.]+)\)", a.help).group(1))
        for a in plan._actions  # noqa: SLF001
        if a.dest in defaults
    }
    assert named == defaults

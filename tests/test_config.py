"""Run config: schema, defaults, one-line errors naming the field, TOML round trip, examples."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from granpack.advice import settings_warnings
from granpack.config import (
    AUTO_ALERT_FRACTION,
    MOVED_SOLVER_KEYS,
    SETTING_TABLES,
    DepositConfig,
    EndGameConfig,
    EquilibriumConfig,
    OutputConfig,
    OverlapConfig,
    PopulationConfig,
    RunConfig,
    SolverConfig,
    ThreadsConfig,
    TimeSteppingConfig,
    load_config,
    load_config_dict,
    moved_keys,
)
from granpack.errors import InputError
from granpack.shapes import ConvexPolyhedron, Pinacoid, Sphere

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
MODELS = (RunConfig, PopulationConfig, TimeSteppingConfig, SolverConfig, OverlapConfig, EndGameConfig, ThreadsConfig,
          EquilibriumConfig, DepositConfig, OutputConfig)
CUBE = [[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]


def pinacoids(**extra) -> dict:
    """A valid bidisperse pinacoid config as parsed TOML, with top-level keys overridden."""
    return {
        "populations": [
            {"shape": "pinacoid", "size": 1.0, "aspect": [1.0, 1.0], "volume_fraction": 0.7},
            {"shape": "pinacoid", "size": 0.3333333333, "aspect": [1.0, 1.0], "volume_fraction": 0.3},
        ],
        **extra,
    }


def with_population(index: int, **keys) -> dict:
    data = pinacoids()
    data["populations"][index] = {**data["populations"][index], **keys}
    return data


def error_of(data: dict) -> str:
    with pytest.raises(InputError) as info:
        load_config_dict(data, "config.toml")
    return str(info.value)


def test_defaults():
    cfg = load_config_dict({"populations": [{"shape": "sphere", "size": 1, "volume_fraction": 1}]})
    assert (cfg.seed, cfg.n_particles, cfg.lateral_size) == (1, 3000, 8.0)
    s, t = cfg.solver, cfg.time_stepping
    assert (t.time_step, s.friction, s.restitution, s.tolerance, s.max_iterations, t.theta) == (5e-3, 0, 0, 1e-4, 2000, 0.5)
    assert t.alert_distance is None and s.check_every == 10
    assert (cfg.overlap.recovery_slop, cfg.overlap.projection_slop, cfg.end_game.mode, cfg.threads.parallel_points) == (
        5e-4, 2e-3, "damping", 2000)
    e = cfg.equilibrium
    assert (e.max_time, e.force_tolerance, e.torque_tolerance, e.kinetic_tolerance, e.wall_tolerance) == (
        300.0, 1e-4, 1e-4, 1e-8, 1e-4)
    assert (e.window, e.check_interval) == (5, 0.25)
    assert (cfg.deposit.method, cfg.deposit.lateral) == ("drop", "walls")
    assert (cfg.output.checkpoint_interval, cfg.output.snapshot_interval) == (5.0, 0.0)
    assert cfg.populations[0].aspect is None and cfg.populations[0].name == "sphere-1"
    assert cfg.resolved_alert_distance == pytest.approx(AUTO_ALERT_FRACTION)


def test_every_field_is_documented():
    for model in MODELS:
        for key, field in model.model_fields.items():
            assert field.description and len(field.description) > 10, f"{model.__name__}.{key}"


def test_pinacoid_defaults_and_derived_names():
    cfg = load_config_dict(
        {"populations": [{"shape": "pinacoid", "size": 1, "volume_fraction": 0.5},
                         {"shape": "pinacoid", "size": 0.5, "aspect": [2, 3], "volume_fraction": 0.5}]}
    )
    assert cfg.populations[0].aspect == (1.0, 1.0)
    assert [p.name for p in cfg.populations] == ["pinacoid-1-1x1", "pinacoid-0.5-2x3"]
    named = load_config_dict(with_population(1, name="small grains"))
    assert named.populations[1].name == "small grains"


def test_message_names_file_and_field_path():
    assert error_of(with_population(1, size=-1)) == "config.toml: populations[1].size: must be > 0 (got -1)"


@pytest.mark.parametrize(
    "data, field, words",
    [
        (pinacoids(color="red"), "color", "unknown key"),
        (pinacoids(time_stepping={"timestep": 1e-3}), "time_stepping.timestep", "allowed: time_step"),
        (pinacoids(solver={"timestep": 1e-3}), "solver.timestep", "allowed: friction"),
        (with_population(0, shape="cube"), "populations[0].shape", "'sphere', 'pinacoid', 'polyhedron', 'mesh' or 'rock'"),
        (with_population(1, size=0), "populations[1].size", "> 0"),
        (with_population(0, aspect=[0.5, 1.0]), "populations[0].aspect", ">= 1"),
        (with_population(0, aspect=[1.0, 0.9]), "populations[0].aspect", ">= 1"),
        (with_population(0, aspect=[1.0]), "populations[0].aspect", "too few"),
        (with_population(0, shape="sphere"), "populations[0].aspect", "only allowed for shapes 'pinacoid' and 'rock'"),
        (with_population(0, volume_fraction=0.6), "populations", "sum to 1"),
        (with_population(0, volume_fraction=-0.1), "populations[0].volume_fraction", ">= 0"),
        (with_population(0, volume_fraction=1.3), "populations[0].volume_fraction", "<= 1"),
        (pinacoids(populations=[]), "populations", "at least 1"),
        ({}, "populations", "missing"),
        (pinacoids(n_particles=0), "n_particles", ">= 1"),
        (pinacoids(n_particles=3000.0), "n_particles", "integer"),
        (pinacoids(seed=True), "seed", "integer"),
        (pinacoids(seed=-1), "seed", ">= 0"),
        (with_population(0, size="1"), "populations[0].size", "number"),
        (with_population(0, size=float("nan")), "populations[0].size", "finite"),
        (pinacoids(lateral_size=2.0), "lateral_size", "at most one periodic image"),
        (pinacoids(time_stepping={"time_step": 0}), "time_stepping.time_step", "> 0"),
        (pinacoids(solver={"friction": -0.1}), "solver.friction", ">= 0"),
        (pinacoids(solver={"restitution": 1.5}), "solver.restitution", "<= 1"),
        (pinacoids(solver={"restitution": -0.5}), "solver.restitution", ">= 0"),
        (pinacoids(time_stepping={"theta": 0.4}), "time_stepping.theta", ">= 0.5"),
        (pinacoids(time_stepping={"alert_distance": 0}), "time_stepping.alert_distance", "> 0"),
        (pinacoids(overlap={"recovery_rate": -1}), "overlap.recovery_rate", ">= 0"),
        (pinacoids(end_game={"mode": "shake"}), "end_game.mode", "'damping' or 'none'"),
        (pinacoids(threads={"parallel_points": -1}), "threads.parallel_points", ">= 0"),
        (pinacoids(solver=3), "solver", "table"),
        (pinacoids(equilibrium={"window": 0}), "equilibrium.window", ">= 1"),
        (pinacoids(deposit={"method": "rain"}), "deposit.method", "'drop' or 'lmgc'"),
        (pinacoids(output={"snapshot_interval": -1}), "output.snapshot_interval", ">= 0"),
        (with_population(1, name="a\nb"), "populations[1].name", "letters"),
        (with_population(1, size=1.0), "populations", "same name"),
        # values that would exhaust memory or the kernels' integers: refused by `check` as by `run`
        (pinacoids(n_particles=10**12), "n_particles", "<= 2e+06"),
        (pinacoids(lateral_size=1e6), "lateral_size", "contact-grid cells"),
        (pinacoids(solver={"max_iterations": 10**20}), "solver.max_iterations", "<= 1e+07"),
        (pinacoids(time_stepping={"time_step": 10.0}, equilibrium={"max_time": 3.0}), "time_stepping.time_step",
         "below equilibrium.max_time"),
        (pinacoids(equilibrium={"check_interval": 1e-9}), "equilibrium.check_interval", "at least time_stepping.time_step"),
    ],
)
def test_bad_values_give_one_line_naming_the_field(data, field, words):
    message = error_of(data)
    assert "\n" not in message
    assert message.startswith(f"config.toml: {field}: "), message
    assert words in message


@pytest.mark.parametrize(
    "vertices, words",
    [
        (None, "required for shape 'polyhedron'"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 3, 0]], "coplanar"),
        (CUBE + [[0.5, 0.5, 0.5]], "not an extreme point"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "at least 4"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0]], "too few numbers"),
    ],
)
def test_bad_polyhedra(vertices, words):
    population = {"shape": "polyhedron", "size": 1.0, "volume_fraction": 1.0}
    if vertices is not None:
        population["vertices"] = vertices
    message = error_of({"populations": [population]})
    assert message.startswith("config.toml: populations[0].vertices"), message
    assert words in message


def test_vertices_only_for_polyhedra():
    assert "only allowed for shape 'polyhedron'" in error_of(with_population(0, vertices=CUBE))


def test_lateral_size_rule_uses_largest_grain_and_alert():
    assert load_config_dict(pinacoids(lateral_size=3.0)).lateral_size == 3.0  # the demo's cell
    assert load_config_dict(pinacoids(lateral_size=2.05)).lateral_size == 2.05  # 2 (1 + 0.02) = 2.04
    assert "2.04" in error_of(pinacoids(lateral_size=2.04))
    assert "= 2.2 d" in error_of(pinacoids(lateral_size=2.1, time_stepping={"alert_distance": 0.1}))
    big = with_population(0, size=1.4) | {"lateral_size": 2.8}
    assert error_of(big).startswith("config.toml: lateral_size: must exceed 2 x (largest grain size 1.4")


def test_make_shape():
    cfg = load_config_dict(
        {"populations": [{"shape": "sphere", "size": 0.5, "volume_fraction": 0.2},
                         {"shape": "pinacoid", "size": 1.0, "aspect": [2, 3], "volume_fraction": 0.3},
                         {"shape": "polyhedron", "size": 0.8, "vertices": CUBE, "volume_fraction": 0.5}]}
    )
    sphere, pinacoid, cube = (p.make_shape() for p in cfg.populations)
    assert isinstance(sphere, Sphere) and sphere.diameter == 0.5
    assert isinstance(pinacoid, Pinacoid) and pinacoid.size == pytest.approx(1.0)
    assert (pinacoid.elongation, pinacoid.flatness) == pytest.approx((2.0, 3.0))
    assert isinstance(cube, ConvexPolyhedron) and cube.size == pytest.approx(0.8)
    assert cube.volume == pytest.approx((0.8 / 3**0.5) ** 3)


ROUND_TRIP_CASES = [
    pinacoids(),
    pinacoids(seed=7, n_particles=12, lateral_size=5.5,
              time_stepping={"alert_distance": 0.035, "time_step": 1e-3},
              solver={"friction": 0.3, "tolerance": 1.666e-4}, overlap={"projection_slop": 1e-3},
              end_game={"mode": "none"}, threads={"parallel_points": 0},
              equilibrium={"max_time": 25.0, "kinetic_tolerance": 3e-9, "window": 2},
              deposit={"method": "lmgc", "lateral": "periodic"},
              output={"checkpoint_interval": 1.0, "snapshot_interval": 0.1}),
    {"populations": [{"shape": "sphere", "size": 1, "volume_fraction": 0.45, "name": "big one"},
                     {"shape": "polyhedron", "size": 0.7, "vertices": CUBE, "volume_fraction": 0.55}]},
]


@pytest.mark.parametrize("data", ROUND_TRIP_CASES)
def test_to_toml_round_trip(data, tmp_path):
    cfg = load_config_dict(data)
    text = cfg.to_toml()
    path = tmp_path / "config.toml"
    path.write_text(text)
    again = load_config(path)
    assert again == cfg
    assert again.to_toml() == text


def test_to_toml_writes_every_default():
    cfg = load_config_dict({"populations": [{"shape": "pinacoid", "size": 1, "volume_fraction": 1}]})
    parsed = tomllib.loads(cfg.to_toml())
    assert parsed["populations"] == [
        {"name": "pinacoid-1-1x1", "shape": "pinacoid", "size": 1.0, "size_definition": "circumscribed",
         "volume_fraction": 1.0, "aspect": [1.0, 1.0]}]
    for table in SETTING_TABLES:
        model = type(getattr(cfg, table))
        unset = {"time_stepping": {"alert_distance"}, "container": {"wall_friction"}}.get(table, set())
        assert set(parsed[table]) == set(model.model_fields) - unset
    assert {"seed", "n_particles", "lateral_size"} <= set(parsed)


def test_with_seed():
    cfg = load_config_dict(pinacoids())
    other = cfg.with_seed(42)
    assert other.seed == 42 and other.populations == cfg.populations and cfg.seed == 1
    with pytest.raises(InputError, match=r"^seed: must be >= 0"):
        cfg.with_seed(-3)


def test_config_is_frozen():
    cfg = load_config_dict(pinacoids())
    with pytest.raises(Exception):
        cfg.seed = 3


def test_file_errors(tmp_path):
    with pytest.raises(InputError, match=r"nope\.toml: no such file$"):
        load_config(tmp_path / "nope.toml")
    with pytest.raises(InputError, match="is a directory"):
        load_config(tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text("seed = 1\nn_particles = \n")
    with pytest.raises(InputError, match=r"bad\.toml: not valid TOML: .*line 2"):
        load_config(bad)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00seed")
    with pytest.raises(InputError, match="not UTF-8"):
        load_config(binary)
    unknown = tmp_path / "unknown.toml"
    unknown.write_text('seed = 1\nfoo = 2\n[[populations]]\nshape = "sphere"\nsize = 1.0\nvolume_fraction = 1.0\n')
    with pytest.raises(InputError, match=r"unknown\.toml: foo: unknown key \(allowed: seed, "):
        load_config(unknown)


# run configs; the campaign specs beside them (with [[mixtures]]) are tested with the campaign
EXAMPLE_FILES = [p for p in sorted(EXAMPLES.glob("*.toml")) if "mixtures" not in tomllib.loads(p.read_text())]


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.name)
def test_examples_load(path):
    cfg = load_config(path)
    # the study's 3000 grains; the demo's 300; the README's 1000 spheres; the graded aggregate's 5000
    # (its coarse fractions within 0.3 %) and its coarse fraction's 1200; the cylinder's 560; the
    # 6700 that fill the 150 x 300 mm mould
    assert cfg.n_particles == {"demo.toml": 300, "aggregate-4-22.toml": 5000, "aggregate-8-22.toml": 1200,
                               "spheres-1000.toml": 1000, "cylinder-spheres.toml": 560,
                               "cylinder-mould-4-22.toml": 6700}.get(path.name, 3000)
    assert load_config_dict(tomllib.loads(cfg.to_toml())) == cfg


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=lambda p: p.name)
def test_examples_follow_the_rules_of_thumb(path):
    # no example should make `granpack check` warn of a setting (a graded one's time step included)
    assert settings_warnings(load_config(path)) == []


def test_examples_readme_lists_every_example():
    # every config key is documented by the generated reference (tests/test_docs.py)
    readme = (EXAMPLES / "README.md").read_text()
    assert len(EXAMPLE_FILES) >= 8
    for path in EXAMPLE_FILES:
        assert f"`{path.name}`" in readme


def test_example_lateral_sizes_and_families():
    lateral = {p.name: load_config(p).lateral_size for p in EXAMPLE_FILES}
    # cells narrowed for a bulk region (tests/test_examples.py): the study's 8 d where it leaves one
    assert lateral == {"demo.toml": 3.0, "aggregate-4-22.toml": 2.5, "pinacoids-bidisperse-30.toml": 3.0, "pinacoids-elongated.toml": 7.0,
                       "pinacoids-flat-elongated.toml": 4.0, "pinacoids-flat.toml": 5.5,
                       "pinacoids-isometric.toml": 8.0, "spheres-bidisperse-30.toml": 4.0, "spheres-mono.toml": 8.0, "spheres-1000.toml": 8.0,
                       "aggregate-8-22.toml": 2.2, "cylinder-spheres.toml": 8.0, "cylinder-mould-4-22.toml": 6.696}
    aspects = {tuple(load_config(EXAMPLES / f).populations[0].aspect) for f in
               ("pinacoids-isometric.toml", "pinacoids-elongated.toml", "pinacoids-flat.toml",
                "pinacoids-flat-elongated.toml")}
    assert aspects == {(1.0, 1.0), (2.0, 1.0), (1.0, 3.0), (2.0, 3.0)}


def test_settings_outside_their_usual_range_are_named_as_advisories():
    assert settings_warnings(load_config_dict(pinacoids())) == []
    notes = settings_warnings(load_config_dict(pinacoids(time_stepping={"time_step": 0.02}, solver={"tolerance": 0.01},
                                                         equilibrium={"max_time": 10.0})))
    assert [note.split(" = ")[0] for note in notes] == ["time_stepping.time_step", "solver.tolerance", "equilibrium.max_time"]


def test_the_flat_solver_table_of_0_1_0_is_read_as_the_grouped_tables():
    flat = {"time_step": 2e-3, "tolerance": 3e-4, "overlap_slop": 1e-3, "end_game": "none", "parallel_points": 0,
            "shake_speed": 1e-3}
    old = load_config_dict(pinacoids(solver=flat))
    new = load_config_dict(pinacoids(time_stepping={"time_step": 2e-3}, solver={"tolerance": 3e-4},
                                     overlap={"projection_slop": 1e-3}, end_game={"mode": "none", "shake_speed": 1e-3},
                                     threads={"parallel_points": 0}))
    assert old == new and old.overlap.projection_slop == 1e-3 and old.end_game.mode == "none"
    assert moved_keys(pinacoids(solver=flat)) == [
        "solver.time_step -> time_stepping.time_step", "solver.overlap_slop -> overlap.projection_slop",
        "solver.end_game -> end_game.mode", "solver.parallel_points -> threads.parallel_points",
        "solver.shake_speed -> end_game.shake_speed"]
    assert moved_keys(pinacoids(solver={"tolerance": 1e-4})) == []
    # the same setting in both places is refused, naming both keys
    both = error_of(pinacoids(solver={"time_step": 2e-3}, time_stepping={"time_step": 1e-3}))
    assert "solver.time_step" in both and "time_stepping.time_step" in both
    # every moved key names a field of its new table
    for table, key in MOVED_SOLVER_KEYS.values():
        assert key in type(getattr(new, table)).model_fields


def test_every_setting_has_one_declaration_that_the_step_defaults_follow():
    from granpack.nscd import StepParameters
    from granpack.settling import step_parameters

    defaults, config = StepParameters(), load_config_dict(pinacoids())
    assert (defaults.time_step, defaults.theta, defaults.tolerance, defaults.max_iterations) == (
        config.time_stepping.time_step, config.time_stepping.theta, config.solver.tolerance, config.solver.max_iterations)
    assert (defaults.overlap_slop, defaults.recovery_slop, defaults.recovery_rate, defaults.recovery_speed) == (
        config.overlap.projection_slop, config.overlap.recovery_slop, config.overlap.recovery_rate,
        config.overlap.recovery_speed)
    assert defaults.parallel_points == config.threads.parallel_points and defaults.alert == config.resolved_alert_distance
    assert defaults == step_parameters(config)  # every field: the step's plain defaults are the config's
    # each table's fields, units and descriptions are written once into the resolved TOML
    text = config.to_toml()
    for table in SETTING_TABLES:
        assert f"[{table}]" in text
    assert "# Time step h. Rule of thumb" in text and "[sqrt(d/g)]" in text


@pytest.mark.parametrize("shape", ["periodic", "box", "cylinder"])
def test_container_shapes_and_wall_friction(shape):
    cfg = load_config_dict({**pinacoids(), "container": {"shape": shape, "wall_friction": 0.3}})
    assert (cfg.container.shape, cfg.container.wall_friction) == (shape, 0.3)
    assert load_config_dict(tomllib.loads(cfg.to_toml())) == cfg
    assert load_config_dict(pinacoids()).container.shape == "periodic"


@pytest.mark.parametrize("table, message", [
    ({"shape": "sphere"}, "container.shape: must be 'periodic', 'box' or 'cylinder' (got 'sphere')"),
    ({"wall_friction": -0.1}, "container.wall_friction: must be >= 0 (got -0.1)"),
    ({"diameter": 3}, "container.diameter: unknown key (allowed: shape, wall_friction)"),
])
def test_container_errors_name_the_field_and_the_allowed_values(table, message):
    with pytest.raises(InputError) as err:
        load_config_dict({**pinacoids(), "container": table}, source="c.toml")
    assert str(err.value) == f"c.toml: {message}"


@pytest.mark.parametrize("shape, words", [("cylinder", "cylinder holds two of the largest grains"),
                                          ("box", "box holds two grains")])
def test_a_container_narrower_than_two_grains_is_refused(shape, words):
    with pytest.raises(InputError) as err:
        load_config_dict({**pinacoids(), "lateral_size": 2.0, "container": {"shape": shape}}, source="c.toml")
    text = str(err.value)
    assert text.startswith("c.toml: lateral_size: must exceed 2 x (largest grain size 1") and words in text
    assert "\n" not in text


def test_a_container_pours_its_deposit_inside_its_walls():
    with pytest.raises(InputError, match="deposit.lateral: must be \"walls\" in a cylinder"):
        load_config_dict({**pinacoids(), "container": {"shape": "cylinder"}, "deposit": {"lateral": "periodic"}})

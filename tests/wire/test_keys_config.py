"""Key space and cell configuration."""


import pytest

from shared.config import CellConfig, load_config
from shared.core.errors import ConfigError, KeyError_
from shared.wire.keys import KeySpace
from tests.util import ROOT
from tools.programs import PROGRAMS, supervisord_conf


def test_keys_are_built_from_the_prefix():
    k = KeySpace("plant/cell7")
    assert k.human_state == "plant/cell7/human/state"
    assert k.command == "plant/cell7/scaler/command"
    assert k.alive("scaler") == "plant/cell7/alive/scaler"
    assert len({k.human_raw, k.human_state, k.goal, k.trajectory, k.command, k.scaler_status, k.joint_state,
                k.safety_events}) == 8


@pytest.mark.parametrize("prefix", ["", "a/*", "a//b", "/a", "a/b/", "a b", "a/**", "x/$y"])
def test_bad_prefixes_are_refused(prefix):
    with pytest.raises(KeyError_):
        KeySpace(prefix)


def test_unknown_service_is_refused():
    with pytest.raises(KeyError_):
        KeySpace().alive("nobody")


def test_the_shipped_config_is_the_built_in_default():
    assert load_config(ROOT / "deploy" / "cell.yaml") == CellConfig()


@pytest.mark.parametrize("text, field", [
    ("ssm: {reaction_time: -1}", "ssm.reaction_time"),
    ("ssm: {stopping_time: .nan}", "ssm.stopping_time"),
    ("scaling: {period: 0}", "scaling.period"),
    ("scaling: {alpha_min: 0.5, alpha_release: 0.4}", "alpha_min"),
    ("scaling: {solver: magic}", "scaling.solver"),
    ("scaling: {await_plan: -0.1}", "scaling.await_plan"),
    ("scaling: {robot_timeout: 0}", "scaling.robot_timeout"),
    ("cell: {prefix: 'a/*'}", "prefix"),
    ("planning: {patience: -1}", "planning.patience"),
    ("planning: {posture_gap: .inf}", "planning.posture_gap"),
    ("planning: {posture_gap: near}", "planning.posture_gap"),
    ("planning: {judge: oracle}", "planning.judge"),
    ("planning: {forecast_horizon: -2}", "planning.forecast_horizon"),
    ("planning: {worth_waiting: -0.5}", "planning.worth_waiting"),
    ("planning: {worth_waiting: .inf}", "planning.worth_waiting"),
    ("planning: {worth_waiting: soon}", "planning.worth_waiting"),
    ("planning: {search: 3}", "unknown key"),
    ("mystery: {}", "unknown section"),
    ("ssm: [1, 2]", "ssm: expected a mapping"),
    ("- just a list", "expected a mapping"),
    ("ssm: {reaction_time: [", "not valid YAML"),
])
def test_bad_config_files_name_the_field(tmp_path, text, field):
    path = tmp_path / "cell.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=field.replace(".", r"\.").replace("*", r"\*")):
        load_config(path)


def test_the_planning_section_reaches_the_planners_options(tmp_path):
    """A configured planning section is what the planning layer decides with, in the cell's planner service,
    hrc demo --sim and the simulation's strategies alike (each builds ReplanOptions from it); a negative posture
    gap (as a sweep's number gives it) is never, as null is."""
    from evidence.strategies import Strategies
    from shared.planning.options import ReplanOptions

    path = tmp_path / "cell.yaml"
    path.write_text("planning: {patience: 3.0, min_gain: 0.2, posture_gap: 1.0, judge: scaling, forecast_horizon: 3.5, "
                    "worth_waiting: 0.75}")
    config = load_config(path)
    options = ReplanOptions(**config.planning.replan_fields())
    assert (options.patience, options.min_gain, options.posture_gap, options.judge) == (3.0, 0.2, 1.0, "scaling")
    assert options.cost.extrapolation == 3.5 and options.cost.spacing == ReplanOptions().cost.spacing
    full = Strategies(config).replanner
    assert full.options.patience == 3.0 and full.options.posture_gap == 1.0 and full.executed is not None
    assert full.cost.options.extrapolation == 3.5                  # the time cost forecasts that far
    assert full.options.worth_waiting == 0.75
    shipped = load_config(ROOT / "deploy" / "cell.yaml").planning.posture_gap
    assert CellConfig().planning.replan_fields()["posture_gap"] == 2.5 == shipped
    paper = load_config(ROOT / "deploy" / "cell-paper.yaml")        # the paper's planner takes no posture
    assert paper.planning.replan_fields()["posture_gap"] is None and paper.ssm.human_acceleration == 0.0
    path.write_text("planning: {posture_gap: -1}")
    assert load_config(path).planning.replan_fields()["posture_gap"] is None
    assert ReplanOptions().patience == CellConfig().planning.patience      # one default, written once
    assert ReplanOptions().cost.extrapolation == CellConfig().planning.forecast_horizon
    assert ReplanOptions().worth_waiting is CellConfig().planning.worth_waiting is None      # never waits ...
    assert load_config(ROOT / "deploy" / "cell.yaml").planning.worth_waiting is None
    path.write_text("planning: {worth_waiting: 0.5}")                                       # ... unless told
    assert load_config(path).planning.replan_fields()["worth_waiting"] == 0.5


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "nope.yaml")


def test_the_shipped_supervisord_conf_is_the_program_table():
    """deploy/supervisord.conf is tools.programs' output (hrc up writes the same into its run folder)."""
    shipped = (ROOT / "deploy" / "supervisord.conf").read_text()
    assert shipped == supervisord_conf(), "regenerate it: python -m tools.programs > deploy/supervisord.conf"
    for program in PROGRAMS:                 # every program, but the optional ones (hrc up --ros2 adds the bridge)
        assert (f"[program:{program.name}]" in shipped and f"-m {program.module} " in shipped) != program.optional




def test_hrc_up_gives_the_tracker_its_cameras_rate(capsys):
    """hrc up --source-rate 15: tracker_ingest's command line in the supervised cell says so, no other program's;
    a rate outside 1-1000 Hz is refused before anything starts."""
    from tools.cli import main

    conf = supervisord_conf((), {"tracker_ingest": ["--source-rate", "15.0"]})
    sections = {s.split("]")[0]: s for s in conf.split("[program:")[1:]}
    assert "-m services.tracker_ingest " in sections["tracker_ingest"]
    assert sections["tracker_ingest"].split("\n")[1].endswith("--source-rate 15.0")
    assert sum("--source-rate" in s for s in sections.values()) == 1
    for bad in ("0", "nan", "2000"):
        assert main(["up", "--source-rate", bad, "--prefix", "hrc/never"]) == 2
        assert "--source-rate must be within [1, 1000] Hz" in capsys.readouterr().err

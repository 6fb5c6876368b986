"""Real people as scenario kinds (evidence.recorded): windows of the human-assembly recordings, placed as
`hrc human from-keypoints` places them, seeded, and run by the same strategies as the scripted kinds."""

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from evidence.recorded import AROUND_X, AROUND_YAW, PLACEMENTS, Placement, around, placed_motion, recorded_scenario
from evidence.scenarios import KNOWN_KINDS, RECORDED_KINDS, SCENARIO_KINDS, kinds_problem, make_scenario
from shared.core.errors import ConfigError
from shared.tracking.motion import RecordedMotion
from shared.tracking.tracked import TrackedMotion
from tests.util import load_bench, run_hrc

FIXTURE = Path(__file__).resolve().parents[1] / "data" / "human-assembly"
SUBSET = FIXTURE / "task1_human1_trial1_first300.txt"            # 300 rows: 10 s at 30 Hz


@pytest.fixture
def two_recordings(tmp_path, monkeypatch):
    """A recordings folder of two files (the shipped subset, and its second half as another), as HRC_RECORDINGS."""
    shutil.copy(SUBSET, tmp_path / "a_first.txt")
    (tmp_path / "b_second.txt").write_text("\n".join(SUBSET.read_text().splitlines()[150:]) + "\n")
    monkeypatch.setenv("HRC_RECORDINGS", str(tmp_path))
    return tmp_path


def test_the_real_kinds_are_known_but_not_among_the_scripted_defaults():
    assert set(RECORDED_KINDS) == {"real_table_edge", "real_step_back", "real_around"}
    assert set(RECORDED_KINDS) <= set(KNOWN_KINDS)
    assert not set(RECORDED_KINDS) & set(SCENARIO_KINDS)


def test_a_seed_is_one_recording_from_one_start_and_the_seeds_cycle_through_the_recordings(two_recordings):
    names = [make_scenario("real_table_edge", seed, 2.0).name for seed in range(4)]
    assert names == ["a_first", "b_second", "a_first", "b_second"]
    a, b = make_scenario("real_table_edge", 2, 2.0), make_scenario("real_table_edge", 2, 2.0)
    assert a.start == b.start and 0.0 <= a.start <= 300 / 30.0 - 2.0
    for t in np.arange(0.0, 2.0, 0.25):
        assert np.array_equal(a.at(t).segments, b.at(t).segments)
    assert {make_scenario("real_table_edge", seed, 2.0).start for seed in (0, 2, 4, 6)} != {a.start}   # starts vary
    longer = make_scenario("real_table_edge", 0, 60.0)                   # longer than the recording: from its start
    assert longer.start == 0.0 and longer.at(59.0) is not None          # its last frame holds


def test_the_placements_are_the_same_person_moved_along_x(two_recordings):
    edge, back = make_scenario("real_table_edge", 1, 3.0), make_scenario("real_step_back", 1, 3.0)
    assert edge.start == back.start
    shift = edge.at(1.0).segments - back.at(1.0).segments
    assert np.allclose(shift[..., 0], PLACEMENTS["table_edge"].x - PLACEMENTS["step_back"].x, atol=2e-5)
    assert np.allclose(shift[..., 1:], 0.0, atol=2e-5)
    assert edge.phase(1.0).startswith("b_second at ")


def test_the_people_are_what_the_cells_tracker_passes_on_as_on_the_processes(two_recordings):
    window = make_scenario("real_table_edge", 2, 3.0)
    tracked = TrackedMotion(placed_motion(two_recordings / "a_first.txt", "table_edge"))
    for t in (0.0, 0.4, 1.7, 2.9):
        a, b = window.at(t), tracked.at(window.start + t)
        assert np.array_equal(a.segments, b.segments) and np.array_equal(a.velocities, b.velocities)
    fitted = window.at(1.0)             # the tracker's fit, not the file's difference from the frame before
    own = placed_motion(two_recordings / "a_first.txt", "table_edge").at(window.start + 1.0)
    assert fitted.velocity_known.all() and not np.allclose(fitted.velocities, own.velocities)


def test_a_windows_samples_are_aged_from_their_capture_as_the_scaler_finds_them(two_recordings):
    """The simulation ages a real kind's people between the recording's 30 Hz frames and judges them stale past
    the bound of that rate (``evidence.sim.sensed``), as ``hrc demo --sim --human`` does with the whole file."""
    from evidence.sim import sensed

    window = make_scenario("real_table_edge", 2, 3.0)
    tracked = TrackedMotion(placed_motion(two_recordings / "a_first.txt", "table_edge"))
    for t in (0.5, 1.01, 2.2):
        taken, interval = window.captured(t)
        whole, measured = tracked.captured(window.start + t)
        assert taken == pytest.approx(whole - window.start) and interval == measured
        assert 0.0 <= t - taken < 1.5 / 30 and interval == pytest.approx(1 / 30, rel=0.05)
        late = sensed(window, t, latency=0.03)
        assert late.age == pytest.approx(t - window.captured(t - 0.03)[0]) and late.age >= 0.03


def test_the_motion_is_what_hrc_human_from_keypoints_writes_and_hrc_demo_reads(tmp_path):
    out = tmp_path / "person.json"
    assert run_hrc("human", "from-keypoints", str(SUBSET), str(out), "--format", "assembly", "--translate",
                   str(PLACEMENTS["table_edge"].x), "0", "1.1").returncode == 0
    written, placed = RecordedMotion.load(out), placed_motion(SUBSET, "table_edge")
    for t in (0.0, 0.5, 4.2, 9.9):
        a, b = written.at(t), placed.at(t)
        assert np.array_equal(a.segments, b.segments) and np.array_equal(a.velocities, b.velocities)
    turned = Placement(-0.3, 0.9)          # a placement's own options give the file the simulation runs
    assert run_hrc("human", "from-keypoints", str(SUBSET), str(out), "--format", "assembly",
                   *turned.options()).returncode == 0
    written, placed = RecordedMotion.load(out), placed_motion(SUBSET, turned)
    for t in (0.0, 4.2):
        assert np.allclose(written.at(t).segments, placed.at(t).segments, atol=2e-5)


def test_around_the_person_is_the_table_edge_person_turned_about_the_base_and_moved_out(two_recordings):
    """The around kind's person is one of the recordings at a distance between one step back and the table's
    edge, turned about the robot's base by up to a quarter turn (beside the sweep's ends), facing the base: the
    same person as straight across, rotated, so only where they stand changes."""
    placements = [around(seed) for seed in range(200)]
    xs, yaws = np.array([p.x for p in placements]), np.array([p.yaw for p in placements])
    assert AROUND_X[0] <= xs.min() < xs.max() <= AROUND_X[1] and -AROUND_YAW <= yaws.min() < yaws.max() <= AROUND_YAW
    assert yaws.min() < -1.2 and yaws.max() > 1.2 and xs.max() - xs.min() > 0.6     # the whole range is drawn
    window = make_scenario("real_around", 3, 4.0)
    assert window.placement == around(3) and window.name == "b_second"
    assert make_scenario("real_around", 3, 4.0).start == window.start == make_scenario("real_table_edge", 3, 4.0).start
    straight = placed_motion(two_recordings / "b_second.txt", Placement(window.placement.x))
    c, s = np.cos(window.placement.yaw), np.sin(window.placement.yaw)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    for t in (0.0, 2.5):
        seen = placed_motion(two_recordings / "b_second.txt", window.placement).at(window.start + t)
        assert np.allclose(seen.segments, straight.at(window.start + t).segments @ turn.T, atol=2e-5)
        assert np.allclose(seen.velocities, straight.at(window.start + t).velocities @ turn.T, atol=1e-3)
    centre = window.at(1.0).segments.reshape(-1, 3).mean(axis=0)       # facing the base from where they stand
    bearing = np.arctan2(centre[1], centre[0])
    assert abs(np.angle(np.exp(1j * (bearing - np.pi - window.placement.yaw)))) < 0.35


def test_without_recordings_the_kinds_say_where_they_looked(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("HRC_RECORDINGS", str(tmp_path / "nowhere"))
    with pytest.raises(ConfigError, match="no recordings .* HRC_RECORDINGS"):
        make_scenario("real_step_back", 0, 12.0)
    with pytest.raises(ConfigError, match="unknown placement"):
        placed_motion(SUBSET, "on_the_table")
    with pytest.raises(ValueError, match="unknown recorded scenario kind"):
        recorded_scenario("real_on_the_table", 0, 1.0)
    assert "no recordings" in kinds_problem(["paper", "real_step_back"])
    assert kinds_problem(["paper"]) is None                            # scripted kinds need no recordings
    assert "unknown or none ['nope']" in kinds_problem(["paper", "nope"])
    assert "unknown or none []" in kinds_problem([]) and kinds_problem([], allow_none=True) is None
    monkeypatch.setattr(sys, "argv", ["compare.py", "--kinds", "real_table_edge", "--scenarios", "2"])
    with pytest.raises(SystemExit) as exit_:
        load_bench("compare").main()
    assert exit_.value.code == 2 and "no recordings" in capsys.readouterr().err


def test_at_the_table_edge_a_real_person_blocks_the_straight_shuttle_and_the_fold_passes(two_recordings):
    """The strategies run a real kind as any other: the person's torso at the table's edge is within reach of
    the straight sweep (the scaling layer alone all but stands), the folded path keeps its links away."""
    from evidence.strategies import Strategies
    from shared.planning.scene import DEFAULT_SCENE, load_scene

    strategies = Strategies(scene=load_scene(DEFAULT_SCENE))
    straight = strategies.run("scale_only", "real_table_edge", 0, 6.0).summary()
    folded = strategies.run("fixed_path", "real_table_edge", 0, 6.0).summary()
    assert straight["violations"] == folded["violations"] == 0
    assert straight["shuttle_progress"] < 0.4 and folded["shuttle_progress"] > 3 * straight["shuttle_progress"]


def test_hrc_sweep_runs_a_real_kind_and_says_when_there_are_no_recordings(tmp_path, monkeypatch):
    monkeypatch.setenv("HRC_RECORDINGS", str(tmp_path / "nowhere"))
    args = ("sweep", "--set", "ssm.reaction_time=0.1", "--strategies", "scale_only", "--kinds", "real_step_back",
            "--scenarios", "1", "--duration", "0.5", "--workers", "1")
    done = run_hrc(*args, "--out", str(tmp_path / "refused"))
    assert done.returncode == 2 and "no recordings" in done.stderr and "HRC_RECORDINGS" in done.stderr
    monkeypatch.setenv("HRC_RECORDINGS", str(FIXTURE))
    done = run_hrc(*args, "--out", str(tmp_path / "ran"))
    assert done.returncode == 0 and "viol 0" in done.stdout, done.stderr[-2000:]
    assert (tmp_path / "ran" / "sweep.csv").read_text().count("\n") == 2            # a header and the point


def test_hrc_scenario_says_where_a_real_person_stands_and_how_to_run_them_on_the_processes(two_recordings, tmp_path):
    """A seed a sweep names in the around kind, taken apart: which recording, from when, where the person stands,
    and the command that writes that person as a motion file for `hrc demo --human` (the same placed person)."""
    import shlex

    done = run_hrc("scenario", "real_around", "3", "--strategies", "scale_only", "--duration", "1")
    assert done.returncode == 0, done.stderr[-2000:]
    window = make_scenario("real_around", 3, 1.0)
    people = done.stdout.splitlines()[1]
    assert people.startswith(f"people: {window.name} from {window.start:.2f} s of it"), done.stdout
    command = shlex.split(done.stdout.splitlines()[2])
    assert command[:3] == ["hrc", "human", "from-keypoints"] and done.stdout.splitlines()[3].strip() == \
        "hrc demo --human person.json"
    out = tmp_path / "person.json"
    command[4] = str(out)
    assert run_hrc(*command[1:]).returncode == 0
    written, placed = RecordedMotion.load(out), placed_motion(two_recordings / f"{window.name}.txt", window.placement)
    for t in (0.0, 2.0):
        assert np.allclose(written.at(t).segments, placed.at(t).segments, atol=2e-5)
    assert "people: scripted" in run_hrc("scenario", "standing", "1", "--strategies", "scale_only",
                                         "--duration", "0.5").stdout

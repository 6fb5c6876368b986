"""The hrc commands that talk to a running cell, against a stand-in cell on loopback (a Zenoh session
that declares the services' liveliness tokens and records what arrives)."""

import re
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from shared.transport.zenoh_session import open_session
from shared.wire.keys import KeySpace
from shared.wire.messages import Goal, HumanRaw, JointState, decode, encode
from tests.util import ROOT, free_port

KEYS = KeySpace("clitest/cell")


@pytest.fixture
def cell():
    port = free_port()
    session = open_session("peer", listen=[f"tcp/127.0.0.1:{port}"])
    received = {"goal": [], "raw": []}
    subs = [session.declare_subscriber(KEYS.goal, lambda s: received["goal"].append(decode(s.payload.to_bytes(), Goal))),
            session.declare_subscriber(KEYS.human_raw,
                                       lambda s: received["raw"].append(decode(s.payload.to_bytes(), HumanRaw)))]
    tokens = [session.liveliness().declare_token(KEYS.alive(name)) for name in ("planner", "tracker_ingest")]
    yield port, received, session
    for t in tokens:
        t.undeclare()
    for s in subs:
        s.undeclare()
    session.close()


def hrc(port, *args):
    return subprocess.run([sys.executable, "-m", "tools.cli", *args, "--connect", f"tcp/127.0.0.1:{port}",
                           "--prefix", KEYS.prefix, "--timeout", "3"], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)


def wait_for(predicate, timeout=3.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not predicate():
        time.sleep(0.02)
    return predicate()


def test_goal_by_name_and_by_angles(cell):
    port, received, _ = cell
    out = hrc(port, "goal", "q_g")
    assert out.returncode == 0, out.stderr
    out = hrc(port, "goal", "0.1", "-0.2", "0.3", "0", "0.5", "0")
    assert out.returncode == 0, out.stderr
    assert wait_for(lambda: len(received["goal"]) == 2)
    assert received["goal"][0].name == "q_g" and np.allclose(received["goal"][0].q, [-1.57, -0.4, 1.17, 0, 1.57, 0])
    assert np.allclose(received["goal"][1].q, [0.1, -0.2, 0.3, 0, 0.5, 0])
    assert received["goal"][0].then.shape == (0, 6)                 # no goal after it unless given
    out = hrc(port, "goal", "q_g", "--then", "q_s")
    assert out.returncode == 0, out.stderr
    assert wait_for(lambda: len(received["goal"]) == 3)
    assert np.allclose(received["goal"][2].then, [[1.57, -0.4, 1.17, 0, 1.57, 0]])


def test_a_goal_sent_to_a_stopped_robot_says_so_and_what_to_do(cell):
    """`hrc goal` reads the robot's state beside sending the goal: to a robot the driver stopped it says so, and that
    the goal is planned again once it runs; with no driver in the cell, that the goal waits for its position."""
    port, received, session = cell
    out = hrc(port, "goal", "q_g")
    assert out.returncode == 0 and "no joint state from the robot driver" in out.stdout, out.stdout
    publisher = session.declare_publisher(KEYS.joint_state)
    stopping = threading.Event()

    def driver():
        while not stopping.is_set():
            publisher.put(encode(JointState(q=np.zeros(6), qd=np.zeros(6), drive_state="stopped:fault",
                                            enabled=False, fault=True, stamp=time.monotonic())))
            time.sleep(0.01)

    feed = threading.Thread(target=driver)
    feed.start()
    try:
        out = hrc(port, "goal", "q_s")
    finally:
        stopping.set()
        feed.join()
    assert out.returncode == 0, out.stderr
    assert "the robot is stopped:fault: the goal is planned again once it runs" in out.stdout, out.stdout
    assert "`hrc recover`" in out.stdout and wait_for(lambda: len(received["goal"]) == 2)


@pytest.mark.parametrize("q, text", [(["1", "2", "3"], "six joint angles"), (["q_x"], "six joint angles"),
                                     (["3", "0", "0", "0", "0", "0"], "joint limits"),
                                     (["a", "0", "0", "0", "0", "0"], "must be numbers"),
                                     (["nan", "0", "0", "0", "0", "0"], "joint limits")])
def test_bad_goals_are_refused_with_a_message(cell, q, text):
    out = hrc(cell[0], "goal", *q)
    assert out.returncode == 2 and text in out.stderr and "Traceback" not in out.stderr
    after = hrc(cell[0], "goal", "q_g", "--then", *q)              # the goal after it, checked the same way
    assert after.returncode == 2 and text in after.stderr and "--then" in after.stderr


def test_goal_without_a_planner_says_so():
    out = hrc(free_port(), "goal", "home")
    assert out.returncode == 1 and "no planner reachable" in out.stderr


def test_human_inject_once_and_moving(cell):
    port, received, _ = cell
    assert hrc(port, "human", "inject", "-0.8", "0", "0.9", "-0.8", "0", "1.4").returncode == 0
    out = hrc(port, "human", "inject", "-0.8", "0", "0.9", "-0.8", "0", "1.4", "--velocity", "0.5", "0", "0",
              "--duration", "0.3", "--rate", "50")
    assert out.returncode == 0, out.stderr
    assert wait_for(lambda: len(received["raw"]) >= 10)
    xs = [m.segments[0, 0, 0] for m in received["raw"][1:]]
    assert xs[-1] > xs[0] + 0.05                    # it moved along +x
    assert hrc(port, "human", "inject", "1", "2", "3", "4", "5", "nan").returncode == 2
    assert hrc(port, "human", "inject", "0", "0", "0", "0", "0", "1", "--velocity", "1", "0", "0").returncode == 2


def test_status_reports_what_the_cell_publishes(cell):
    port, _, session = cell
    from shared.wire.messages import HumanState
    pub = session.declare_publisher(KEYS.joint_state)
    people = session.declare_publisher(KEYS.human_state)
    proc = subprocess.Popen([sys.executable, "-m", "tools.cli", "status", "--connect", f"tcp/127.0.0.1:{port}",
                             "--prefix", KEYS.prefix, "--timeout", "2"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 2.5
    while time.monotonic() < end:
        pub.put(encode(JointState(q=np.zeros(6), qd=np.zeros(6), drive_state="running:operation_enabled",
                                  enabled=True, fault=False)))
        now = time.monotonic()                   # a 30 Hz camera whose states reach the cell 60 ms after capture
        people.put(encode(HumanState(segments=np.array([[[-1.0, 0, 0.9], [-1.0, 0, 1.5]]]), radii=np.array([0.17]),
                                     velocities=np.zeros((1, 2, 3)), velocity_known=np.array([True]), valid=True,
                                     sample_stamp=now - 0.06, sample_interval=1 / 30, stamp=now)))
        time.sleep(0.05)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "planner up" in out and "scaler down" in out and "running:operation_enabled" in out
    assert "people:   1 capsule(s), 30.0 Hz, 60 ms from capture to the tracker" in out, out


def test_human_replay(cell, tmp_path):
    port, received, _ = cell
    path = tmp_path / "walk.csv"
    rows = ["t,ax,ay,az,bx,by,bz,radius"] + [f"{k * 0.02:.2f},{-1.5 + 0.01 * k},0,0.9,{-1.5 + 0.01 * k},0,1.45,0.17"
                                              for k in range(10)]
    path.write_text("\n".join(rows) + "\n")
    out = hrc(port, "human", "replay", str(path), "--speed", "2")
    assert out.returncode == 0, out.stderr
    # the demo's own feed: each frame once at its time (100 Hz at --speed 2), a late one skipped, never a burst
    sent, skipped = map(int, re.search(r"published (\d+) pose\(s\), (\d+) skipped", out.stdout).groups())
    assert "sending at 100.0 Hz" in out.stdout and sent + skipped == 10 and sent >= 5
    assert wait_for(lambda: len(received["raw"]) == sent)
    assert received["raw"][-1].segments[0, 0, 0] == pytest.approx(-1.41)     # the last frame always goes
    times = [m.sample_time for m in received["raw"]]
    assert np.diff(times) == pytest.approx(np.full(sent - 1, 0.01)) or skipped
    received["raw"].clear()
    out = hrc(port, "human", "replay", str(path), "--latency", "0.05")    # a camera 50 ms behind
    assert out.returncode == 0, out.stderr
    sent = int(re.search(r"published (\d+) pose\(s\)", out.stdout).group(1))
    assert sent >= 1 and wait_for(lambda: len(received["raw"]) == sent)
    assert all(m.stamp - m.sample_time >= 0.05 - 1e-3 for m in received["raw"])   # sent 50 ms after its capture
    out = hrc(port, "human", "replay", str(path), "--latency", "1")
    assert out.returncode == 2 and "stale" in out.stderr
    path.write_text("t,ax\n1,2\n")
    out = hrc(port, "human", "replay", str(path))
    assert out.returncode == 2 and "line 1" in out.stderr and "Traceback" not in out.stderr


def _publish_cell_state(session, stop):
    """The robot and one person, as the cell would publish them, every 20 ms until stop is set."""
    from shared.wire.messages import HumanState
    pub_js, pub_h = session.declare_publisher(KEYS.joint_state), session.declare_publisher(KEYS.human_state)
    q = np.array([1.57, -0.4, 1.17, 0.0, 1.57, 0.0])
    while not stop.is_set():
        now = time.monotonic()
        pub_js.put(encode(JointState(q=q, qd=np.zeros(6), drive_state="enabled", enabled=True, fault=False,
                                     stamp=now)))
        pub_h.put(encode(HumanState(segments=np.array([[[-1.0, 0, 0.9], [-1.0, 0, 1.5]]]), radii=np.array([0.17]),
                                    velocities=np.zeros((1, 2, 3)), velocity_known=np.ones(1, bool), valid=True,
                                    sample_stamp=now, stamp=now)))
        time.sleep(0.02)


def test_view_saves_what_the_cell_publishes(cell, tmp_path):
    import threading

    from rerun.chunk import RrdReader

    port, _, session = cell
    stop = threading.Event()
    feeder = threading.Thread(target=_publish_cell_state, args=(session, stop), daemon=True)
    feeder.start()
    try:
        out = hrc(port, "view", "--save", str(tmp_path / "view.rrd"), "--duration", "2")
    finally:
        stop.set()
        feeder.join()
    assert out.returncode == 0, out.stderr
    rows = {}
    for chunk in RrdReader(tmp_path / "view.rrd").stream():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    assert rows.get("/world/robot/measured", 0) > 20 and rows.get("/world/humans", 0) > 20, rows


def listening(port: int) -> list[str]:
    """Local addresses (hex, as in /proc/net/tcp and tcp6) listening on a port."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as f:
            for line in f.readlines()[1:]:
                local, state = line.split()[1], line.split()[3]
                if state == "0A" and int(local.rsplit(":", 1)[1], 16) == port:
                    found.append(local.rsplit(":", 1)[0])
    return found


def test_view_serves_the_viewer_on_loopback_only(cell):
    import urllib.request

    port, _, _ = cell
    web, grpc = free_port(), free_port()
    proc = subprocess.Popen([sys.executable, "-m", "tools.cli", "view", "--connect", f"tcp/127.0.0.1:{port}",
                             "--prefix", KEYS.prefix, "--duration", "6", "--web-port", str(web), "--grpc-port", str(grpc)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_for(lambda: listening(web) and listening(grpc), timeout=15), "the viewer did not start"
        assert set(listening(web)) | set(listening(grpc)) == {"0100007F"}          # 127.0.0.1, nothing else
        assert urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=5).status == 200
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert f"http://127.0.0.1:{web}/" in out
    assert wait_for(lambda: not listening(web), timeout=5)                         # the viewer is gone too


def test_a_reader_that_leaves_early_is_no_error(cell):
    """`hrc status | grep -q running`: grep leaves at the first match, and the command's next line meets a closed
    pipe; that ends it quietly, with no traceback."""
    port = cell[0]
    proc = subprocess.Popen([sys.executable, "-m", "tools.cli", "status", "--connect", f"tcp/127.0.0.1:{port}",
                             "--prefix", KEYS.prefix, "--timeout", "1"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    proc.stdout.close()                     # the reader is gone before the first line
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and "Traceback" not in err and "BrokenPipe" not in err, err

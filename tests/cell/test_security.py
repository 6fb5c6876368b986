"""Security of the multi-host deployment, shown on loopback: a router with mutual TLS and access control
(services.router --tls-dir --acl), the real scaler as a TLS client of it, and sessions of other identities.
Only the scaler's joint commands and only tracker_ingest's human states get through; a certificate the
ACL does not know receives nothing; a session without a certificate, or over plain TCP, gets no link.
The single-host configuration listens on loopback only."""

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest
import zenoh

from shared.core.errors import ConfigError
from shared.transport.acl import IDENTITIES, PUBLISHERS, access_control
from shared.transport.pki import TlsIdentity, make_cell_pki
from shared.transport.zenoh_session import await_liveliness, check_endpoints, make_config, open_session
from shared.wire.keys import KeySpace
from shared.wire.messages import HumanRaw, HumanState, JointCommand, JointState, decode, encode
from tests.util import ROOT, free_port

KEYS = KeySpace("hrc/cell1")
Q = np.array([1.57, -0.4, 1.17, 0.0, 1.57, 0.0])


def _spawn(*argv):
    return subprocess.Popen([sys.executable, "-m", *argv], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _stop(proc):
    proc.terminate()
    try:
        return proc.communicate(timeout=10)[0]
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate()[0]


@pytest.fixture(scope="module")
def secured(tmp_path_factory):
    certs = make_cell_pki(tmp_path_factory.mktemp("tls"), [*IDENTITIES, "intruder"])
    endpoint = f"tls/127.0.0.1:{free_port()}"
    router = _spawn("services.router", "--listen", endpoint, "--tls-dir", str(certs), "--acl", "--prefix",
                    KEYS.prefix)
    scaler = None
    try:
        deadline = time.monotonic() + 20
        while True:                                    # the router answers once its TLS listener is up
            try:
                probe = open_session("client", connect=[endpoint], tls=TlsIdentity.from_dir(certs, "operator"))
                break
            except ConfigError:
                assert router.poll() is None and time.monotonic() < deadline, _stop(router)
                time.sleep(0.3)
        scaler = _spawn("services.scaler", "--mode", "client", "--connect", endpoint, "--tls-dir", str(certs),
                        "--prefix", KEYS.prefix, "--log-level", "WARNING")
        assert await_liveliness(probe, KEYS.alive("scaler"), 60.0), _stop(scaler)
        yield certs, endpoint, probe
        probe.close()
    finally:
        logs = [_stop(p) for p in (scaler, router) if p is not None]
        print("\n".join(logs)[-3000:])


def _session(certs, name, endpoint):
    return open_session("client", connect=[endpoint], tls=TlsIdentity.from_dir(certs, name))


def _collect(session, key, kind):
    """What reaches the session from others (its own publications are delivered locally, not checked here)."""
    got = []

    def on_sample(sample):
        try:
            got.append(decode(sample.payload.to_bytes(), kind))
        except Exception as exc:           # a test collector: keep what broke, for the assertion message
            got.append(exc)
    return got, session.declare_subscriber(key, on_sample, allowed_origin=zenoh.Locality.REMOTE)


def test_only_the_scaler_commands_the_robot_and_only_the_tracker_publishes_humans(secured):
    certs, endpoint, _ = secured
    driver, monitor = _session(certs, "robot_driver", endpoint), _session(certs, "safety_monitor", endpoint)
    tracker, planner = _session(certs, "tracker_ingest", endpoint), _session(certs, "planner", endpoint)
    operator, intruder = _session(certs, "operator", endpoint), _session(certs, "intruder", endpoint)
    bridge = _session(certs, "ros2_bridge", endpoint)
    try:
        raws, sub4 = _collect(tracker, KEYS.human_raw, HumanRaw)
        commands, sub1 = _collect(driver, KEYS.command, JointCommand)
        humans, sub2 = _collect(monitor, KEYS.human_state, HumanState)
        stolen, sub3 = _collect(intruder, f"{KEYS.prefix}/**", JointCommand)
        time.sleep(1.0)
        forged = encode(JointCommand(q=Q + 0.5, qd=np.zeros(6), trajectory_version=99, s=0.0))
        person = HumanState(segments=np.zeros((1, 2, 3)) + 2.0, radii=np.array([0.1]),
                            velocities=np.zeros((1, 2, 3)), velocity_known=np.array([True]), valid=True,
                            sample_stamp=time.monotonic())
        for k in range(30):
            # the robot driver's joint state: the scaler holds the measured position and commands it
            driver.put(KEYS.joint_state, encode(JointState(q=Q, qd=np.zeros(6), drive_state="running:x",
                                                           enabled=True, fault=False, seq=k)))
            planner.put(KEYS.command, forged)              # a valid certificate, but not the scaler's
            intruder.put(KEYS.command, forged)             # a certificate the ACL does not know
            tracker.put(KEYS.human_state, encode(person))
            operator.put(KEYS.human_state, encode(HumanState(**{**person.__dict__, "radii": np.array([0.9])})))
            bridge.put(KEYS.command, forged)               # the ROS 2 bridge sends people and goals in, no commands
            bridge.put(KEYS.human_state, encode(HumanState(**{**person.__dict__, "radii": np.array([0.8])})))
            bridge.put(KEYS.human_raw, encode(HumanRaw(source="ros2", sample_time=time.monotonic(),
                                                       segments=person.segments, radii=person.radii, seq=k)))
            time.sleep(0.02)
        time.sleep(0.5)
        assert commands, "the scaler's commands did not reach the driver"
        assert all(np.allclose(c.q, Q) for c in commands), "a command from another identity got through"
        assert humans and all(np.allclose(h.radii, [0.1]) for h in humans), "a human state not from the tracker"
        assert stolen == [], "a session with an unknown certificate received the cell's messages"
        assert raws and all(r.source == "ros2" for r in raws), "the ROS 2 bridge's people did not reach the tracker"
        for sub in (sub1, sub2, sub3, sub4):
            sub.undeclare()
    finally:
        for s in (driver, monitor, tracker, planner, operator, intruder, bridge):
            s.close()


def test_a_session_without_a_certificate_or_over_plain_tcp_gets_no_link(secured, tmp_path):
    certs, endpoint, _ = secured
    no_cert = make_config("client", connect=[endpoint])
    no_cert.insert_json5("transport/link/tls", json.dumps({"root_ca_certificate": str(certs / "ca.pem")}))
    no_cert.insert_json5("connect/timeout_ms", "2000")
    with pytest.raises(zenoh.ZError):
        zenoh.open(no_cert)
    with pytest.raises(ConfigError, match="cannot open a client session"):
        open_session("client", connect=[endpoint.replace("tls/", "tcp/")])
    other_ca = make_cell_pki(tmp_path / "other", ["scaler"])       # a certificate of another CA
    with pytest.raises(ConfigError):
        open_session("client", connect=[endpoint], tls=TlsIdentity.from_dir(other_ca, "scaler"))


def test_the_shipped_secure_router_config_is_the_generated_policy():
    def without_none(value):
        if isinstance(value, dict):
            return {k: without_none(v) for k, v in value.items() if v is not None}
        if isinstance(value, list):
            return [without_none(v) for v in value]
        return value

    config = zenoh.Config.from_file(str(ROOT / "deploy" / "zenoh" / "secure-router.json5"))
    assert without_none(json.loads(config.get_json("access_control"))) == access_control("hrc/cell1")
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("transport/link/tls/enable_mtls")) is True
    client = zenoh.Config.from_file(str(ROOT / "deploy" / "zenoh" / "secure-client.json5"))
    assert json.loads(client.get_json("scouting/multicast/enabled")) is False
    assert {k for k, keys in PUBLISHERS.items() if "command" in keys} == {"scaler"}
    assert {k for k, keys in PUBLISHERS.items() if "human_state" in keys} == {"tracker_ingest"}


def test_single_host_config_listens_on_loopback_only():
    config = zenoh.Config.from_file(str(ROOT / "deploy" / "zenoh" / "single-host.json5"))
    endpoints = json.loads(config.get_json("listen/endpoints"))
    assert endpoints and all(e.startswith(("tcp/127.0.0.1:", "tcp/[::1]:")) for e in endpoints)
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    for bad in ("tcp/0.0.0.0:7447", "tls/10.0.0.2:7447", "udp/127.0.0.1:7447", "tcp/localhost:7447"):
        with pytest.raises(ConfigError):
            check_endpoints([bad])


def test_router_refuses_acl_without_tls_and_missing_certificates(tmp_path):
    out = subprocess.run([sys.executable, "-m", "services.router", "--acl"], cwd=ROOT, capture_output=True,
                         text=True, env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=30)
    assert out.returncode == 2 and "--acl needs --tls-dir" in out.stderr
    out = subprocess.run([sys.executable, "-m", "services.router", "--tls-dir", str(tmp_path), "--listen",
                          f"tls/127.0.0.1:{free_port()}"], cwd=ROOT, capture_output=True, text=True,
                         env=dict(os.environ, PYTHONPATH=str(ROOT)), timeout=30)
    assert out.returncode == 2 and "missing" in out.stderr and "hrc certs" in out.stderr

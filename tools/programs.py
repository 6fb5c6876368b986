"""The cell's programs, described once: what each one runs, in which order, at which niceness, and how it
joins the CAN bus and Zenoh.

Three starters read this table and nothing else: supervisord's configuration for `hrc up`
(``supervisord_conf``; ``deploy/supervisord.conf`` is its output, kept for integrators who run
supervisord themselves, and a test keeps the two equal), the demo's launcher (``tools.launch``) and the
hardware-in-the-loop harness (``tests/hil/harness.py``). Every Zenoh program is a peer listening on its
own loopback port; all but the hub (the robot driver) connect to the hub's (peers do not forward; gossip
meshes them).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Program:
    """One process of the cell. ready: a line its output holds once it is up (the bus programs, which
    have no liveliness token to wait for, or whose bring-up must finish before the next starts)."""

    name: str
    module: str                    # run as `python -m <module>`
    on_can: bool = False           # takes --interface (and --channel)
    on_zenoh: bool = True          # takes --prefix, --listen and, unless it is the hub, --connect
    hub: bool = False              # the endpoint every other peer connects to
    reads_config: bool = True      # takes --config (the cell configuration YAML)
    niceness: int = 0              # outside the control path: yields the CPU to the safety chain
    priority: int = 30             # supervisord's start order (lower first)
    startsecs: int = 1             # supervisord counts a start as good after this long
    ready: str = ""
    optional: bool = False         # started only when asked (hrc up --ros2), never by hrc demo

    def argv(self, *, interface: str, channel: str | None = None, prefix: str = "", listen: str = "",
             connect: str = "", config: str | None = None, extra: tuple[str, ...] | list[str] = ()) -> list[str]:
        """The arguments after `python -m`: the module and what this program needs to join the cell (the
        configuration file only to the programs that read one)."""
        args = [self.module]
        if self.on_can:
            args += ["--interface", interface] + (["--channel", channel] if channel else [])
        if self.on_zenoh:
            args += ["--prefix", prefix, "--listen", listen] + ([] if self.hub else ["--connect", connect])
        if config is not None and self.reads_config:
            args += ["--config", str(config)]
        return args + list(extra)


# The planner (nice 10) and the monitor (nice 5) yield the CPU to the control path: on a small machine a
# restarting planner (OMPL, compiled kernels) otherwise starved the driver's SYNC thread past the drives'
# watchdog (found by hrc faults on a 2-core VM). The safety chain, and below it the monitor, ask for SCHED_FIFO
# once warmed up (shared.scheduling); the monitor's niceness holds for its warm-up and where the OS refuses.
PROGRAMS: tuple[Program, ...] = (
    Program("hwsim", "hwsim", on_can=True, on_zenoh=False, reads_config=False, priority=10,
            ready="hwsim: PRBT emulator"),
    Program("robot_driver", "services.robot_driver", on_can=True, hub=True, priority=20, startsecs=3,
            ready="robot_driver: drives up"),
    Program("tracker_ingest", "services.tracker_ingest", reads_config=False, ready="tracker_ingest:"),
    Program("scaler", "services.scaler", ready="scaler:"),
    Program("planner", "services.planner", niceness=10, ready="planner:"),
    Program("safety_monitor", "services.safety_monitor", niceness=5, ready="safety_monitor:"),
    Program("ros2_bridge", "services.ros2_bridge", niceness=10, priority=40, ready="ros2_bridge:", optional=True),
)
BY_NAME = {p.name: p for p in PROGRAMS}
SERVICES = tuple(p.name for p in PROGRAMS if p.on_zenoh and not p.optional)   # in start order, the hub first

_HEADER = """\
; The whole cell under supervisord: the PRBT emulator and every service, restarted when they crash,
; stopped cleanly (SIGTERM, then SIGKILL after stopwaitsecs) when supervisord stops. Generated from
; tools/programs.py (the one description of the cell's programs; `hrc up` writes this into its run folder):
; edit that table, not this file. `hrc up` starts it (inside a private network namespace when the CAN bus
; is udp_multicast) with these variables set:
;   HRC_RUN     a run folder (sockets, logs)       HRC_PYTHON  the interpreter of the installed project
;   HRC_CAN     python-can interface               HRC_PREFIX  the cell's key prefix
;   HRC_PORT    the first of six loopback ports (robot driver, then one per service; the sixth: ros2_bridge)
; The planner (nice 10) and the monitor (nice 5) yield the CPU to the control path; once warmed up, the
; safety chain and, below it, the monitor take SCHED_FIFO themselves (shared/scheduling.py).
[supervisord]
nodaemon=true
logfile=%(ENV_HRC_RUN)s/supervisord.log
pidfile=%(ENV_HRC_RUN)s/supervisord.pid
childlogdir=%(ENV_HRC_RUN)s

[unix_http_server]
file=%(ENV_HRC_RUN)s/supervisor.sock

[supervisorctl]
serverurl=unix://%(ENV_HRC_RUN)s/supervisor.sock

[rpcinterface:supervisor]
supervisor.rpcinterface_factory = supervisor.rpcinterface:make_main_rpcinterface
"""


def _port(k: int) -> str:
    return f"%(ENV_HRC_PORT{k if k else ''})s"


def source_rate_args(rate: float | None) -> dict[str, list[str]]:
    """The extra arguments that declare a people tracker's frame rate (Hz) to tracker_ingest (``hrc up --source-rate``,
    ``hrc demo --human FILE``): none where there is no rate or one the service would refuse
    (``shared.tracking.tracker.declarable``)."""
    from shared.tracking.tracker import declarable  # here, not at import: the program table loads nothing compiled

    return {"tracker_ingest": ["--source-rate", repr(float(rate))]} if rate is not None and declarable(rate) else {}


def supervisord_conf(optional: tuple[str, ...] = (), extra: dict[str, list[str]] | None = None) -> str:
    """supervisord's configuration of the whole cell (the values come from HRC_* environment variables), with
    the optional programs named in `optional` (ros2_bridge) and each program's extra arguments (`extra`, by
    name: ``hrc up --source-rate`` gives tracker_ingest its camera's rate)."""
    sections = [_HEADER]
    zenoh = [p for p in PROGRAMS if p.on_zenoh]
    for program in (p for p in PROGRAMS if not p.optional or p.name in optional):
        port = _port(zenoh.index(program)) if program.on_zenoh else ""
        argv = program.argv(interface="%(ENV_HRC_CAN)s", prefix="%(ENV_HRC_PREFIX)s",
                            listen=f"tcp/127.0.0.1:{port}", connect=f"tcp/127.0.0.1:{_port(0)}",
                            extra=(extra or {}).get(program.name, []))
        nice = f"nice -n {program.niceness} " if program.niceness else ""
        sections.append(f"""
[program:{program.name}]
command={nice}%(ENV_HRC_PYTHON)s -m {' '.join(argv)}
priority={program.priority}
startsecs={program.startsecs}
autorestart=true
stopsignal=TERM
stopwaitsecs=5
redirect_stderr=true
stdout_logfile=%(ENV_HRC_RUN)s/{program.name}.log
""")
    return "".join(sections)


if __name__ == "__main__":          # python -m tools.programs > deploy/supervisord.conf
    print(supervisord_conf(), end="")

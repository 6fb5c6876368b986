"""Key space and cell configuration: the tests that start a process or a network namespace (the rest, in-process, are in
tests/wire/test_keys_config.py)."""

from tests.util import ROOT
from tools.programs import PROGRAMS


def test_every_program_accepts_the_arguments_the_table_gives_it():
    """Each program's own --help against tools.programs: a flag the table passes that the program does not
    take would stop it at start-up (`hrc demo --config` once gave tracker_ingest a --config it refuses); the
    flags `hrc demo --no-beta` and `hrc demo --human FILE` (the file's frame rate declared) add too."""
    import subprocess
    import sys

    from tools.demo import service_args

    extra = service_args(True, 15.0)
    assert set(extra) <= {program.name for program in PROGRAMS}
    for program in PROGRAMS:
        argv = program.argv(interface="udp_multicast", channel="239.0.0.1", prefix="p", listen="tcp/127.0.0.1:1",
                            connect="tcp/127.0.0.1:2", config="cell.yaml")
        argv += extra.get(program.name, [])          # hrc demo --no-beta --human FILE adds these
        flags = {a for a in argv if a.startswith("--")}
        out = subprocess.run([sys.executable, "-m", program.module, "--help"], capture_output=True, text=True,
                             timeout=60, cwd=ROOT)
        assert out.returncode == 0, out.stderr
        missing = {f for f in flags if f not in out.stdout}
        assert not missing, (program.name, missing)
        assert ("--config" in out.stdout) == program.reads_config, program.name

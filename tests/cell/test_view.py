"""The 3D view: capsule poses, the closest pair, and a recording written and read back: the tests that start a process
or a network namespace (the rest, in-process, are in
tests/tools/test_view.py)."""





def test_rerun_is_told_to_send_no_analytics():
    """rerun's SDK and viewer would send usage analytics to the internet: the project gives them a private
    configuration with analytics off, which the viewer binary itself reads back."""
    import json
    import os
    import subprocess

    from tools.view import no_analytics, rerun_binary

    home = no_analytics()
    assert json.loads((home / "rerun" / "analytics.json").read_text())["analytics_enabled"] is False
    assert os.environ["XDG_CONFIG_HOME"] == str(home)
    shown = subprocess.run([rerun_binary(), "analytics", "config"], capture_output=True, text=True, timeout=30)
    assert json.loads(shown.stdout)["analytics_enabled"] is False

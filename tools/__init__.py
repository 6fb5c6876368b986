"""The operator's tools: the `hrc` command line, the demo and its report, the fault campaign and its
judging, the 3D view, and the launchers that start a cell."""

"""The planning layer: the static scene, collision checking, OMPL paths, time parameterisation, the
SSM-aware time cost, the path search, and the replanner (horizon check, merge, keep-or-replace)."""

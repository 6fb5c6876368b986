"""The scaling layer: the convex problem of one control cycle (problem) and the stateful layer that
solves it every cycle and asks for replans (layer)."""

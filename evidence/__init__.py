"""The evidence: the in-process simulation of both layers, scripted people, the zone-based baseline and
the strategies compared side by side (bench/compare.py)."""

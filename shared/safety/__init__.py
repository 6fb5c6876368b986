"""ISO/TS 15066 speed and separation monitoring: the limit (ssm), the independent monitor's check
(monitor) and the measured reaction chain (latency)."""

"""The ``ros2`` section of a cell's configuration: the ROS 2 graph the bridge joins (``services.ros2_bridge``).

domain_id: the ROS_DOMAIN_ID of the ROS 2 graph (0-232), the first chunk of every rmw_zenoh key. router: the
Zenoh endpoint of the ROS 2 graph's router (rmw_zenohd, ``tcp/127.0.0.1:7447`` by default on a ROS 2 host)
that the bridge connects to besides the cell; empty: none (ROS 2 tools then connect to the bridge's own
endpoint). Free of compiled code and of rosbags, so reading a configuration loads nothing heavy."""

from __future__ import annotations

from dataclasses import dataclass

from shared.core.errors import ConfigError


@dataclass(frozen=True)
class Ros2Parameters:
    domain_id: int = 0
    router: str = ""

    def __post_init__(self) -> None:
        if isinstance(self.domain_id, bool) or not isinstance(self.domain_id, int) or not 0 <= self.domain_id <= 232:
            raise ConfigError(f"ros2.domain_id: expected a ROS domain id, 0 to 232, got {self.domain_id!r}")
        if not isinstance(self.router, str) or (self.router and not self.router.startswith(("tcp/", "tls/"))):
            raise ConfigError(f"ros2.router: expected a Zenoh endpoint (tcp/HOST:PORT) or '', got {self.router!r}")

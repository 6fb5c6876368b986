"""Who may publish what: the Zenoh router's access control for one cell (the multi-host deployment).

Sessions are identified by the common name of their TLS client certificate (shared.transport.pki). The router
denies by default; it lets every identity of the cell declare subscribers, liveliness tokens and queries
on the cell's keys and receive every publication, but takes a publication (put) only from the identities
below for each key. So only the scaler may publish joint commands, only tracker_ingest human states, and
so on; an unknown certificate may do nothing, a session without one does not get a link at all (mTLS).
"""

from __future__ import annotations

from shared.wire.keys import KeySpace

# identity -> the KeySpace attributes it may publish on
PUBLISHERS: dict[str, tuple[str, ...]] = {
    "scaler": ("command", "scaler_status"),
    "tracker_ingest": ("human_state", "safety_events"),
    "planner": ("trajectory", "safety_events"),
    "robot_driver": ("joint_state", "safety_events", "latency", "drive_lag"),
    "safety_monitor": ("safety_events", "monitor"),
    "operator": ("goal", "human_raw", "driver_request"),        # the hrc tools, the tracker bridge, an HMI
    # the ROS 2 bridge: goals and people from ROS 2, its refusal reports; its ROS 2 keys and tokens (outside the
    # cell's prefix) are not taken here: a secured cell reaches ROS 2 through a ROS 2 router (ros2.router)
    "ros2_bridge": ("goal", "human_raw", "safety_events"),
}
IDENTITIES = (*PUBLISHERS, "router")
DECLARATIONS = ["declare_subscriber", "declare_queryable", "query", "reply", "liveliness_token",
                "declare_liveliness_subscriber", "liveliness_query"]


def access_control(prefix: str) -> dict:
    """The router's `access_control` section for the cell with this key prefix."""
    keys = KeySpace(prefix)
    everything = f"{keys.prefix}/**"
    rules = [{"id": "declare", "permission": "allow", "flows": ["ingress", "egress"], "messages": DECLARATIONS,
              "key_exprs": [everything]},
             {"id": "deliver", "permission": "allow", "flows": ["egress"], "messages": ["put"],
              "key_exprs": [everything]}]
    subjects = [{"id": name, "cert_common_names": [name]} for name in IDENTITIES]
    policies = [{"id": "everyone", "rules": ["declare", "deliver"], "subjects": list(IDENTITIES)}]
    for name, attributes in PUBLISHERS.items():
        rules.append({"id": f"publish-{name}", "permission": "allow", "flows": ["ingress"], "messages": ["put"],
                      "key_exprs": [getattr(keys, a) for a in attributes]})
        policies.append({"id": f"{name}-publishes", "rules": [f"publish-{name}"], "subjects": [name]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}

"""ROS 2 (Jazzy) on the wire, pure: message types and their CDR bytes (rosbags' Jazzy type store), the key
expressions, liveliness tokens, GIDs and attachments of rmw_zenoh (ros2/rmw_zenoh docs/design.md), and the
cell's messages as ROS 2 messages and back. No I/O: the bridge service and the MCAP writer use it."""

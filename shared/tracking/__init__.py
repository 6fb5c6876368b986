"""People: the tracker (raw capsules in, capsules with velocities out), recorded motion files and
body keypoints turned into capsules."""

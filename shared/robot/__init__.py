"""The PRBT: kinematics (pinocchio), joint limits and link capsules, and the URDF and YAML they come from."""

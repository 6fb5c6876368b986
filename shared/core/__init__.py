"""The vocabulary every block uses: the project's errors, tracked humans as capsules, capsule
distances, and nominal trajectories q(s)."""

"""The bench SLAM."""

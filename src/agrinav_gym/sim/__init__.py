"""pybullet world built from a Scenario: terrain, robot, plants."""

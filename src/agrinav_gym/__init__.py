"""AgriNav Gym: pybullet Summit-XL environments built from ``scenario_gen`` scenarios."""

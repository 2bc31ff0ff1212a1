"""Controllers behind one interface (DWB, pure pursuit, PPO) — filled by the policies issue."""

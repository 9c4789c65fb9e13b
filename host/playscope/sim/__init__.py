"""Simulator: robot with backlash B(q) + f_remain, effect library, endoscope camera, sessions and video."""

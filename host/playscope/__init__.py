"""playscope host utility: in situ backlash estimation (B(q), f_remain) for continuum robots."""

__version__ = "0.1.0"

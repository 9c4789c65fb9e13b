"""Device link on the host: frame codec (the C one, through cffi), transports, board commands."""

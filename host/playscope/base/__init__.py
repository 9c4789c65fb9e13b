"""Shared basics every layer uses: errors, atomic writes and the output guard, JSON values, and
the one loader of the firmware's C (native: constants, the core, the desktop boards)."""

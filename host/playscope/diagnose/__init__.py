"""Sim-to-real gap diagnosis: held-out gap vs noise floor, localisation, attribution to library effects."""

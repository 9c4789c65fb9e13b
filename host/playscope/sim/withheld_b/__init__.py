"""Second, independent withheld-effect generator for the blind self-test of `playscope diagnose`.

Written apart from the first generator (`sim.withheld`) and from the diagnosis: it imports
neither, nor `playscope.fit.model` or the simulator's effect code (tests/python/sim/test_blind_imports.py
walks the imports). Its own forms throughout: a sine-sweep excitation with pauses (not back-and-
forth legs at constant speed), a play whose width follows a tanh of q, a cubic bending map,
AR(1) sensor noise quantised to 0.01 deg at 80 Hz, one other-author form of every library effect,
and three effects the library lacks (a lightly damped ringing rung at each reversal, a cogging
of the actuator, random slips of the tendon anchor). `generator.py` holds all of it.
"""

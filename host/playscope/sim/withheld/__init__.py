"""Generator of withheld effects for the blind self-test of `playscope diagnose`.

Written apart from the diagnosis on purpose: nothing here imports `playscope.diagnose`,
`playscope.fit.model` or the simulator's effect code (`sim.core`, `sim.effects`), and the
diagnosis' fitted forms import nothing from here (tests/python/sim/test_blind_imports.py walks
the imports). The plant uses its own forms (clearance evaluated at q with a Lorentzian width, a
tanh-softened bending map, its own angle sensor), and every library effect has at least two
physically different implementations (`variants.VARIANTS`), so the diagnosis has to recognise
the effect, not its formula.

plant.py     base plant (play as a clearance, bending map, angle sensor) and the stage pipeline
variants.py  the effect implementations, two or more per library effect, plus out-of-library ones
oracle.py    an effect-free reference fit written apart from the diagnoser (identifiable in situ?)
"""

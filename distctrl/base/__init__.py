"""The ground floor: the vocabulary every other package of distctrl speaks.

Enumerations of kinds (:mod:`.kinds`: filter types, sensor sources) and of states, transitions and
codes (:mod:`.states`: HLI DistanceControl, FCT-M3 §8). Nothing here imports any other part of
distctrl, so the parameters, the errors, the cycle core and everything above can all use it without
a circle (docs/architecture.md).
"""

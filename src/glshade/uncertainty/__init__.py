"""The uncertainty budget of a phase-measuring station (``glshade budget``, docs/budget.md).

A station reconstructs the part with what it *believes* of its own geometry (its
calibration: :attr:`glshade.scene.Scene.calibration`), while the light it records comes
from the truth. The budget draws beliefs about the truth from stated standard deviations
(:mod:`.spec`: a TOML ``[uncertainty]`` table of dotted parameter paths), one input at a
time and all together (:mod:`.draws`), measures every draw by phase measuring on the
measuring engine (:mod:`.run`: in this process or on Dask, resumable, its output folder
locked), and says what each input contributes to the slope map, the fitted depth and the
dent's position, and in total (:mod:`.report`). :mod:`.closed_forms` holds the first-order
sensitivities of a flat mirror the budget is checked against.

No GL in this package but through the engine, and nothing here imports the command line.
"""

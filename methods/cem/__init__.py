"""Containment Exclusion Mode (Romano, Uppaluru, Rastgoftar, Atkins): the ideal-fluid flow around
failed vehicles (uniform flow + one doublet per failure, eq. 1-6) and its inversion (Algorithms 1-2)
in ``flow`` and ``kernels``, the hand-back and safety record in ``handback``, and the run (activations,
the tick, the metrics) in ``mode``. Used by the ``cem`` avoidance plugin."""

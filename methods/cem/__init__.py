"""Containment Exclusion Mode (Romano, Uppaluru, Rastgoftar, Atkins): the ideal-fluid flow around
failed vehicles (uniform flow + one doublet per failure, eq. 1-6) and its inversion (Algorithms 1-2).
Used by the ``cem`` avoidance plugin."""

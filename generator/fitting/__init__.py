"""The fitter: a scene (``arenabench fit``) or a preset with every parameter pinned or open
(``arenabench twin``) from one real image of an arena; camera, markers, greys, light, boxes,
rectified texture, records and report.
"""

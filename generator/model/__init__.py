"""The scene model and its geometry: the scene records, where things lie on the arena, the camera
and
lens, light and shading, distractors, and the sampler that draws scenes from a preset.
"""

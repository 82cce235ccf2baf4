"""Data files of the generator (the competition's arena texture, the shader, the preset files) and
the
modules that read them: the competition arena's measured geometry and the content-keyed texture
store.
"""

"""Off-screen rendering with pyrender: the renderer and its interface, the pinned pyrender
internals,
arena textures, edge models and image degradations.
"""

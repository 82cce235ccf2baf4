"""One sample (scene, render, ground truth) and datasets of them on disk: the writer, the COCO
export,
and the OpenGL check every rendering command runs first.
"""

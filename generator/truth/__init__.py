"""Analytic ground truth of a scene: silhouettes, areas, marker corners and occlusion, and the
derived
facts that explain failures.
"""

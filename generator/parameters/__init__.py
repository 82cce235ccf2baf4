"""The parameter space: one declaration per parameter (:mod:`.params`), values and ``--set``
overrides
(:mod:`.param_values`), preset files (:mod:`.preset_files`) and the preset table (:mod:`.presets`).
"""

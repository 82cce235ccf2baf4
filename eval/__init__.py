"""arenabench.eval: pipeline adapters, metrics, reports and robustness sweeps."""

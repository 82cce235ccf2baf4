"""arenabench.generator: scene model, sampling, off-screen rendering and analytic ground truth."""

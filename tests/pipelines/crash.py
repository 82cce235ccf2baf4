"""A pipeline that crashes at once."""

raise RuntimeError("deliberate crash in the test pipeline")

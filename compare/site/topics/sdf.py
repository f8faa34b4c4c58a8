"""The SDF scenario on the site: its default cells are small kernels (the per-call page)."""
SMALL = True

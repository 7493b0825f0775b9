"""Scene folders of synthetic parts in the ABC-NEF layout, and the built-in scenes.

`writer` writes any part's scene (renders, edge maps by a detector, ground truth); `scene` holds
the default scene of `edgedog demo` and the exact box that tests and benchmarks use.
"""

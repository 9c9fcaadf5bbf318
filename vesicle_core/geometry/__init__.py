"""Geometry of the triangulated membrane: the icosphere and quasi-uniform sphere meshes mapped onto an ellipsoid,
their UGRID description, and the surface quantities computed on them.
"""

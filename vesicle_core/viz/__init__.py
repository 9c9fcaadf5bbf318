"""Figures of the reference paper (matplotlib) and 3D renders of the membrane (pyvista, or matplotlib).
"""

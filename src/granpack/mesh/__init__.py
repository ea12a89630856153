"""Grain surfaces and finite-element meshes of a packing (docs/method/meshing.md).

``surfaces``: every grain as a closed triangle surface (STL, OBJ, PLY; trimesh). ``region``: the box,
the shrink of touching grains and the ITZ, decided before meshing (numpy). ``_gmsh``: the conforming
tetrahedral mesh (gmsh, an optional extra). ``volume``: the mesh written (gmsh, meshio) and checked.
"""

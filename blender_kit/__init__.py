"""Blender scenes and Cycles references shared by tests/ and bench/ (each imports this package, neither imports the
other): ``scene`` builds scenes through the bpy module, ``cycles`` sets Cycles up as a Whitted reference,
``scatter`` is the Geometry Nodes scatter graph. bpy is imported lazily: importing this package needs no Blender.
"""

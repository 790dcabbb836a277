"""USD geometry -> tracer geometry: meshes (triangulation, primvars, subdivision through
:mod:`tracer.geometry.subdivision`), implicit gprims, curves and points, NURBS patches, skinned meshes, instancing
(point instancers and native instances), transforms and their time samples.

May import: pxr, the tracer, and :mod:`usd_io.errors`. Nothing here reads materials, lights or cameras."""

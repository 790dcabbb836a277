"""Geometry the tracer intersects and shades: per-triangle surface attributes (barycentric interpolation of normals,
UVs and tangents; :mod:`.surface`), motion over the shutter (:mod:`.motion`), shared-mesh instances
(:mod:`.instances`) and Catmull-Clark / Loop subdivision on numpy (:mod:`.subdivision`).

May import: the tracer's leaf modules (``vec``, ``jit``, ``sampling``, ``heap``, ``colorspace``, ``settings``).
Nothing here knows about materials, lights, the scene container or Embree."""

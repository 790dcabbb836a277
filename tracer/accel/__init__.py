"""Ray intersection: our binding to Embree 4's C API (:mod:`.embree`), the per-scene accelerator with its flat and
instanced layouts (:mod:`.accelerator`), and the alpha filter that runs a material's cut-out program inside Embree's
traversal (:mod:`.alpha`).

May import: the leaf modules, :mod:`tracer.geometry`, :mod:`tracer.shading` (the alpha programs),
:mod:`tracer.lights` (linking masks) and the scene container (:mod:`tracer.scene`)."""

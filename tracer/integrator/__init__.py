"""The seed's Cast-Ray as a wavefront (:mod:`.wavefront`: eye, shadow, reflection and transmission rays, depth by
depth over queues), the tile loop that feeds it and the film (:mod:`.tiles`), compositing: holdouts and shadow
catchers (:mod:`.compose`), and the denoiser's guides (:mod:`.guides`: Cycles' Denoising Albedo and Normal).

May import: everything below it (leaf modules, geometry, shading, lights, scene, accel, film). Imported only by
the front doors (:mod:`tracer.render`, :mod:`tracer.session`, :mod:`tracer.farm`, :mod:`tracer.explain`)."""

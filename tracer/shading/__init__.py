"""Shading: what a surface does with light. The material table (:mod:`.materials`), textures (:mod:`.texture`),
the seed's local model (:mod:`.local`: Lambert + Blinn-Phong), microfacet BSDFs and their lobes (:mod:`.bsdf`,
:mod:`.lobes`, :mod:`.ggx_tables`), and the shading language: the node IR (:mod:`.graph`), the one node table
(:mod:`.nodes`), parameter-style surfaces written as graphs (:mod:`.principled`), the compiler to a flat program
(:mod:`.compiler`, :mod:`.closures`), the VM that runs it per hit (:mod:`.vm`, :mod:`.ops`, :mod:`.spaces`), the
world's program (:mod:`.world`) and Cycles' procedurals (:mod:`.procedural`).

May import: the tracer's leaf modules and :mod:`tracer.geometry` (surface attributes the VM reads at a hit).
Nothing here knows about lights, the scene container, Embree or the integrator."""

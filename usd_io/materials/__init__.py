"""``UsdShade`` materials -> the tracer's shader graphs: binding resolution and the material table
(:mod:`.table`), UsdPreviewSurface inputs through their networks (:mod:`.network`, :mod:`.shade_types`,
:mod:`.preview_ranges`), MaterialX (:mod:`.mtlx`, :mod:`.mtlx_graph`), Arnold (:mod:`.arnold`,
:mod:`.arnold_patterns`), OmniPBR (:mod:`.omnipbr`) and the choice between them (:mod:`.surfaces`), texture files and
assets (:mod:`.texture_files`, :mod:`.texture_assets`) and the primvars a material reads (:mod:`.primvars`).

May import: pxr, MaterialX (optional), the tracer, :mod:`usd_io.geometry` (primvar readers) and
:mod:`usd_io.exporters`."""

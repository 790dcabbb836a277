"""Light sources: point, spot, distant and area emitters and their sampling (:mod:`.emitters`), the world as an
environment (:mod:`.environment`: a constant colour or a lat-long map with its importance sampling), the sky's
shadowed ambient term (:mod:`.sky`), and light and shadow linking (:mod:`.linking`).

May import: the tracer's leaf modules only. Lights know nothing of shading, geometry or Embree."""

"""Which application wrote a stage, and the light units that application meant (docs/usd.md, "Two readings").

Filled in by the light-units work; :data:`KIT_EV` is the exposure Omniverse Kit's intensities need in the
tracer's units (lights and OmniPBR emission alike).
"""

from __future__ import annotations

#: Omniverse Kit: intensities (lights, OmniPBR emissive_intensity) are scaled by 2^KIT_EV.
KIT_EV = -9.0

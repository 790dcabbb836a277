"""Cycles' procedural textures and colour nodes as scalar numba functions for the shader VM (issue #20).

- :mod:`.hash`: Jenkins lookup3 and PCG hashes (``util/hash.h``)
- :mod:`.noise`: Perlin noise 1-4D and the Noise Texture's fractals
- :mod:`.voronoi`: the Voronoi Texture
- :mod:`.patterns`: Wave, Magic, Gradient, Brick, Checker, White Noise
- :mod:`.color`: HSV/HSL, Hue/Saturation/Value, Blackbody, Wavelength, RGB to BW, Mix, Color Ramp, curves

Each scalar function is a compiled kernel the VM's kernels call; each texture has a numpy ``*_array`` form. What each
matches, and how it was measured against Cycles: docs/materials-api.md ("Procedural textures and colour functions").
"""

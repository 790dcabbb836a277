"""Renders whose every pixel has a closed-form value: texture orientation, the notes' classic glass weights against
Fresnel's slab transmittance, and what ε does (acne without it, light leaks with too much of it).

Each scene is built so that one wrong sign, swap or weight changes the asserted pixels."""

from __future__ import annotations

import numpy as np
import pytest

from tracer import Camera, PointLight, RenderSettings, SceneBuilder
from tracer import render
from tracer.shading.texture import sample_bilinear

from tracer_scenes import quad

N = 8  # texture size and image size: one pixel per texel


def _texture():
    """An asymmetric 8×8 texture: red grows to the right (column), green downwards (row 0 = the image's top as
    files store it), blue marks the top-left texel only."""
    rows, cols = np.mgrid[0:N, 0:N]
    tex = np.stack([(cols + 0.5) / N, (rows + 0.5) / N, np.zeros((N, N))], axis=-1).astype(np.float32)
    tex[0, 0, 2] = 1.0
    return tex


def _textured_quad_scene(uv_rotation=0):
    """The unit square z = 0 with uv = (x, y), seen from +z by an orthographic camera that frames it exactly
    (image right = +x, image up = +y), lit only by an ambient term of 1 so each pixel shows its texel."""
    b = SceneBuilder()
    tex = b.add_texture(_texture())
    m = b.add_material("textured", diffuse=(1, 1, 1), diffuse_texture=tex)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    uv = v[:, :2]
    b.add_mesh(v, [[0, 1, 2], [0, 2, 3]], material=m, uvs=uv, name="square")
    b.camera = Camera.look_at((0.5, 0.5, 5), (0.5, 0.5, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    b.ambient = np.ones(3, np.float32)
    return b.build()


def test_texture_is_seen_upright_and_not_transposed():
    """A texture file's top row is at v = 1 (UsdUVTexture, Blender and OIIO agree): seen from the front with u to
    the right and v up, the rendered image is the texture image itself, texel for texel."""
    img = render(_textured_quad_scene(), RenderSettings(width=N, height=N, samples=1)).rgb
    np.testing.assert_allclose(img, _texture(), atol=1e-6)
    assert img[0, 0, 2] == 1.0 and img[-1, -1, 2] == 0.0  # the marked texel is top-left, not bottom-left


def test_bilinear_lookup_of_the_texture_file_convention():
    """sample_bilinear at texel centres (s right, t up) returns the texel of row (1 − t)·H, column s·W."""
    tex = _texture()
    rows, cols = np.mgrid[0:N, 0:N]
    st = np.stack([(cols + 0.5) / N, 1 - (rows + 0.5) / N], axis=-1).reshape(-1, 2)
    np.testing.assert_allclose(sample_bilinear(tex, st).reshape(N, N, 3), tex, atol=1e-6)
    # halfway between the two top-left texels horizontally: their mean (bilinear, not nearest)
    mid = sample_bilinear(tex, np.array([[1.0 / N, 1 - 0.5 / N]]))[0]
    np.testing.assert_allclose(mid, (tex[0, 0] + tex[0, 1]) / 2, atol=1e-6)


def test_lookup_repeats_outside_the_unit_square():
    """Repeat wrapping (the lookup's documented mode, UsdUVTexture's and Blender's default): (s + i, t + j) gives the
    texel at (s, t) for any integers, and across the seam at s = 0 the lookup blends the first and last columns."""
    tex = _texture()
    rng = np.random.default_rng(5)
    st = rng.uniform(0, 1, (200, 2))
    shift = rng.integers(-3, 4, (200, 2))
    np.testing.assert_allclose(sample_bilinear(tex, st + shift), sample_bilinear(tex, st), atol=1e-5)
    seam = sample_bilinear(tex, np.array([[0.0, 1 - 0.5 / N]]))[0]  # on the left edge, top row
    np.testing.assert_allclose(seam, (tex[0, 0] + tex[0, -1]) / 2, atol=1e-6)


# ------------------------------------------------------------------------------------------ glass weights
BG = np.array([0.2, 0.5, 0.9], np.float32)


def _pane_scene(ior=1.5):
    """A glass pane (a thin box, faces ⟂ z) between an orthographic camera looking down −z and the background;
    behind the camera a black wall catches every reflection, so only light transmitted through the pane arrives."""
    b = SceneBuilder()
    glass = b.add_material("glass", diffuse=(0, 0, 0), transmission=1.0, ior=ior)
    black = b.add_material("black", diffuse=(0, 0, 0))
    lo, hi = np.array([-2, -2, -0.1]), np.array([2, 2, 0.1])
    v = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])], float)
    faces = [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7],
             [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]
    b.add_mesh(v, faces, material=glass, name="pane")
    quad(b, (0, 0, 10), 50.0, black, "wall")  # faces +z; the camera (at z = 5) sees past its back
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    b.background = BG
    return b.build()


def test_classic_weights_pass_everything_through_glass():
    """The notes' weights (fresnel=False): no reflection off glass unless TIR, so the pane is invisible."""
    img = render(_pane_scene(), RenderSettings(width=4, height=4, fresnel=False)).rgb
    np.testing.assert_allclose(img, np.broadcast_to(BG, img.shape), atol=1e-6)


def test_fresnel_weights_give_the_slab_transmittance():
    """Fresnel at normal incidence, F = ((n−1)/(n+1))²; a slab lets through (1−F)² Σ F^{2k} = (1−F)/(1+F) of the
    background (the inner reflections that go backwards end on the black wall)."""
    n = 1.5
    f = ((n - 1) / (n + 1)) ** 2
    img = render(_pane_scene(n), RenderSettings(width=4, height=4, max_depth=12, min_weight=0.0)).rgb
    np.testing.assert_allclose(img, np.broadcast_to(BG * (1 - f) / (1 + f), img.shape), rtol=1e-4)


def test_transmission_tint_filters_each_crossing():
    """The tint multiplies the transmitted RayColor at each crossing (as Cycles' glass colour does): with the notes'
    weights a tinted pane passes the background × tint², channel by channel."""
    tint = np.array([0.9, 0.5, 0.25], np.float32)
    scene = _pane_scene()
    scene.materials.transmission_tint[0] = tint
    img = render(scene, RenderSettings(width=4, height=4, fresnel=False)).rgb
    np.testing.assert_allclose(img, np.broadcast_to(BG * tint**2, img.shape), rtol=1e-5)


# ------------------------------------------------------------------------------------------------------ ε
def _lit_floor_with_block():
    """A floor lit by a point light straight above a small block standing on it; the camera looks down."""
    b = SceneBuilder()
    grey = b.add_material("grey", diffuse=(0.5, 0.5, 0.5))
    quad(b, (0, 0, 0), 20.0, grey, "floor")
    s = 0.5  # a 1 × 1 × 0.5 block on the floor, from z = 0 to 0.5
    v = np.array([[x, y, z] for z in (0.0, s) for y in (-0.5, 0.5) for x in (-0.5, 0.5)], float)
    faces = [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4], [2, 6, 3], [3, 6, 7],
             [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]
    b.add_mesh(v, faces, material=grey, name="block")
    b.add_light(PointLight(position=(3, 0, 4), intensity=(40.0,) * 3))
    b.camera = Camera.look_at((0, 0, 12), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=6.0, vertical_aperture=6.0)
    return b.build()


def _floor_radiance(x, y):
    """Closed form of the unshadowed floor: L = a/π · I·cosθ/r² (I the radiant intensity)."""
    d = np.array([3 - x, -y, 4.0])
    r2 = d @ d
    return 0.5 / np.pi * 40.0 * (4.0 / np.sqrt(r2)) / r2


def test_default_epsilon_lights_the_floor_exactly_and_keeps_the_contact_shadow():
    scene = _lit_floor_with_block()
    img = render(scene, RenderSettings(width=60, height=60, samples=1)).rgb
    xs = (np.arange(60) + 0.5) / 60 * 6 - 3
    # A row of lit floor away from the block (y = 2.05): every pixel equals the closed form (no acne).
    row = 60 - 1 - int((2.05 + 3) / 6 * 60)
    y = 3 - (row + 0.5) / 60 * 6
    expected = np.array([_floor_radiance(x, y) for x in xs])
    np.testing.assert_allclose(img[row, :, 0], expected, rtol=2e-3)
    # The shadow of the block on the floor, just beside its left face (x = −0.55, light at +x): dark.
    col = int((-0.55 + 3) / 6 * 60)
    assert img[30, col, 0] < 1e-6


def test_a_vanishing_epsilon_shows_acne_and_a_huge_one_leaks_light():
    """Why ε exists (the notes' shadow ray starts ε off the surface): with ε ≈ 0 shadow rays hit the surface they
    leave (speckled self-shadowing on the lit floor); with ε larger than the block, the contact shadow lights up."""
    scene = _lit_floor_with_block()
    clean = render(scene, RenderSettings(width=60, height=60, samples=1)).rgb[..., 0]
    acne = render(scene, RenderSettings(width=60, height=60, samples=1, epsilon=1e-12)).rgb[..., 0]
    lit = clean > 0.01
    speckled = np.mean(acne[lit] < 0.5 * clean[lit])
    assert speckled > 0.01, f"only {speckled:.1%} of the lit floor self-shadowed with ε ≈ 0"
    leaky = render(scene, RenderSettings(width=60, height=60, samples=1, epsilon=1.0)).rgb[..., 0]
    col = int((-0.55 + 3) / 6 * 60)
    assert clean[30, col] < 1e-6 < leaky[30, col]


def test_shadow_rays_stop_at_the_light():
    """A point light between the floor and a ceiling: the ceiling above the light casts no shadow on the floor
    (a shadow ray is the segment from the point to the light, the notes' t < distance to the light), so the floor
    is the closed form of the unshadowed point light everywhere."""
    b = SceneBuilder()
    grey = b.add_material("grey", diffuse=(0.5, 0.5, 0.5))
    quad(b, (0, 0, 0), 20.0, grey, "floor")
    quad(b, (0, 0, 4.5), 20.0, grey, "ceiling")  # just above the light
    b.add_light(PointLight(position=(3, 0, 4), intensity=(40.0,) * 3))
    b.camera = Camera.look_at((0, 0, 3), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=6.0, vertical_aperture=6.0)
    img = render(b.build(), RenderSettings(width=30, height=30, samples=1)).rgb[..., 0]
    xs = (np.arange(30) + 0.5) / 30 * 6 - 3
    ys = 3 - (np.arange(30) + 0.5) / 30 * 6
    expected = np.array([[_floor_radiance(x, y) for x in xs] for y in ys])
    np.testing.assert_allclose(img, expected, rtol=2e-3)


# ------------------------------------------------------------------------------------------- Blinn-Phong
@pytest.mark.parametrize("tilt_deg", [0.0, 8.0])
def test_blinn_phong_highlight_has_the_normalised_lobe(tilt_deg):
    """A purely specular plane (R_s = 0.5, exponent e) under a sun of irradiance E, seen by an orthographic camera
    from straight above: L = R_s·E·(e+8)/(8π)·(n·h)^e·(n·l) — with the sun straight above too, h = n; tilting the
    sun by α makes n·h = cos(α/2) and n·l = cos α."""
    from tracer import DistantLight

    e, rs, irr = 50.0, 0.5, 2.0
    a = np.radians(tilt_deg)
    b = SceneBuilder()
    m = b.add_material("shiny", diffuse=(0, 0, 0), specular=(rs, rs, rs), exponent=e)
    quad(b, (0, 0, 0), 10.0, m, "plane")
    b.add_light(DistantLight(direction=(np.sin(a), 0, -np.cos(a)), irradiance=(irr,) * 3))
    b.camera = Camera.look_at((0, 0, 5), (0, 0, 0), up=(0, 1, 0), projection="orthographic",
                              horizontal_aperture=1.0, vertical_aperture=1.0)
    img = render(b.build(), RenderSettings(width=4, height=4, shading="classic")).rgb  # the notes' model
    expected = rs * irr * (e + 8) / (8 * np.pi) * np.cos(a / 2) ** e * np.cos(a)
    np.testing.assert_allclose(img, expected, rtol=1e-4)


# ------------------------------------------------------------------------------------------------------ sRGB
def _ocio(pixels, src, dst):
    """OpenColorIO's conversion (OIIO's built-in config: the sRGB standard's piecewise curve), an independent
    reference for ours."""
    import OpenImageIO as oiio

    pixels = np.ascontiguousarray(pixels, np.float32)
    h, w, c = pixels.shape
    buf = oiio.ImageBuf(oiio.ImageSpec(w, h, c, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(0, w, 0, h, 0, 1, 0, c), pixels)
    out = oiio.ImageBufAlgo.colorconvert(buf, src, dst)
    assert not out.has_error, out.geterror()
    return np.asarray(out.get_pixels(oiio.FLOAT)).reshape(h, w, c)


LINEAR, SRGB = "Linear Rec.709 (sRGB)", "sRGB Encoded Rec.709 (sRGB)"


def test_png_is_srgb_encoded_as_opencolorio_does_it(tmp_path):
    """A PNG written by the tracer holds OCIO's sRGB encoding of the linear pixels, to the 8-bit step (the curve's
    linear toe, the 2.4 exponent and the clip above 1 all show on this ramp)."""
    from tracer import read_image, write_image

    ramp = np.concatenate([np.linspace(0, 0.01, 32), np.geomspace(0.01, 1.0, 96), [1.5, 4.0]]).astype(np.float32)
    rgb = np.stack([ramp, ramp[::-1], np.full_like(ramp, 0.18)], -1)[None]
    path = str(tmp_path / "ramp.png")
    write_image(path, rgb)
    got = np.round(read_image(path) * 255)
    expected = np.round(np.clip(_ocio(rgb, LINEAR, SRGB), 0, 1) * 255)
    assert np.abs(got - expected).max() <= 1
    assert got[0, -1, 0] == 255 and got[0, 0, 0] == 0 and got[0, 0, 2] == 118  # 0.18 linear is sRGB 118/255


def test_srgb_textures_decode_as_opencolorio_does_it():
    """Each 8-bit sRGB code decodes to OCIO's linear value (OCIO's own evaluation differs by < 0.03 %)."""
    from tracer.colorspace import srgb_to_linear

    codes = (np.arange(256, dtype=np.float32) / 255)[None, :, None].repeat(3, axis=2)
    np.testing.assert_allclose(srgb_to_linear(codes), _ocio(codes, SRGB, LINEAR), rtol=1e-3, atol=1e-7)


def test_classic_model_mirrors_a_smooth_principled_metal():
    """shading="classic" on a Principled row: a smooth metal (metallic 1, roughness 0) is the notes' mirror with
    k_m·tint = base colour — the floor seen in it is the floor × base, channel by channel; a rough one (0.6) has no
    mirror ray at all (g = 0)."""
    import tracer

    def scene(rough):
        b = tracer.SceneBuilder()
        metal = b.add_material("metal", base_color=(0.9, 0.5, 0.2), metallic=1.0, roughness=rough)
        b.add_mesh([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2), (0, 2, 3)], material=metal)
        b.camera = tracer.Camera.look_at((0, 0, 3), (0, 0, 0), up=(0, 1, 0), focal_length=100.0,
                                         horizontal_aperture=24.0, vertical_aperture=24.0)
        b.background = (0.2, 0.4, 0.6)
        return b.build()

    st = tracer.RenderSettings(width=8, height=8, samples=1, shading="classic", max_depth=1)
    smooth = tracer.render(scene(0.0), st).rgb
    np.testing.assert_allclose(smooth, np.broadcast_to((0.9 * 0.2, 0.5 * 0.4, 0.2 * 0.6), smooth.shape), atol=1e-5)
    rough = tracer.render(scene(0.6), st).rgb
    np.testing.assert_allclose(rough, 0.0, atol=1e-6)


@pytest.mark.parametrize("shading", ["classic", "principled"])
def test_partial_mirror_mixes_local_and_reflected_by_k_m(shading):
    """The notes' c = (1 − k_m)·c_local + k_m·tint·RayColor(reflected) in both local models: a Lambert plane
    (no specular) facing the camera under a sun along the view axis, reflecting the background. c_local =
    base·E/π, RayColor = background."""
    import tracer

    base, e, k_m, bg = np.array([0.6, 0.3, 0.2]), 2.0, 0.4, np.array([0.2, 0.4, 0.6])
    b = tracer.SceneBuilder()
    m = b.add_material("half", base_color=tuple(base), specular=0.0, k_m=k_m)
    b.add_mesh([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2), (0, 2, 3)], material=m)
    b.add_light(tracer.DistantLight(direction=(0, 0, -1), irradiance=(e, e, e)))
    b.camera = tracer.Camera.look_at((0, 0, 3), (0, 0, 0), up=(0, 1, 0), focal_length=100.0,
                                     horizontal_aperture=24.0, vertical_aperture=24.0)
    b.background = tuple(bg)
    img = tracer.render(b.build(), tracer.RenderSettings(width=8, height=8, samples=1, shading=shading, max_depth=1))
    want = (1 - k_m) * base * e / np.pi + k_m * bg
    np.testing.assert_allclose(img.rgb, np.broadcast_to(want, img.rgb.shape), rtol=1e-4)


def test_a_minified_texture_is_filtered_to_its_mean_not_aliased():
    """Mip-mapping: a 512² texture of one-texel black/white checks on a 2 × 2 quad, seen by a 64 × 64 orthographic
    view of it (each pixel covers 8 × 8 texels, one eye sample per pixel), renders at its mean 0.5 everywhere
    (level 3 of the chain is exactly grey). Read from the full image, the samples — a quarter texel off the texel
    centres — would give 0.25s and 0.75s."""
    import tracer

    n, size = 512, 64
    checks = ((np.add.outer(np.arange(n), np.arange(n)) % 2).astype(np.float32))[..., None].repeat(3, axis=2)
    b = tracer.SceneBuilder()
    tex = b.add_texture(checks)
    m = b.add_material("checks", base_color=(1, 1, 1), base_color_texture=tex, specular=0.0)
    b.add_mesh([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2), (0, 2, 3)], material=m,
               uvs=[(0, 0), (1, 0), (1, 1), (0, 1)])
    quarter = 0.25 * 2.0 / n  # a quarter texel in world units
    b.camera = tracer.Camera.look_at((quarter, quarter, 3), (quarter, quarter, 0), up=(0, 1, 0),
                                     projection="orthographic", horizontal_aperture=2.0 - 4 * quarter,
                                     vertical_aperture=2.0 - 4 * quarter)
    b.ambient = (1.0, 1.0, 1.0)  # unlit: each pixel shows its texel (R_a·L_a, a = the texture)
    img = tracer.render(b.build(), tracer.RenderSettings(width=size, height=size, samples=1)).rgb
    np.testing.assert_allclose(img, 0.5, atol=0.02)

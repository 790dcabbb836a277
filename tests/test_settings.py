"""RenderSettings is the one definition of every render setting (issue #22): each field, given a value other than
its default, reaches the settings of ``whitted render``, of ``whitted explain`` and of the farm's UsdSource through
the flag its metadata names, the add-on's ``scene.whitted`` property of the same name through F12's settings, and
the session's integrator key when the packed tables depend on it. A field that is not a flag or a property says
where it comes from instead."""

from __future__ import annotations

import dataclasses

import pytest

from tracer.settings import INTEGRATOR_FIELDS, SETTINGS, RenderSettings, default_of, integrator_key

#: A valid value other than the default for every field (a new field fails the walk until it is listed here).
CHANGED = {"width": 40, "height": 30, "samples": 3, "adaptive_threshold": 0.05, "adaptive_min_samples": 8,
           "max_depth": 1, "epsilon": 1e-3, "fresnel": False,
           "shadows": False, "light_samples": 9, "sky_samples": 4, "terminal_rays": True, "shading": "classic",
           "max_transparent": 0, "min_weight": 0.25, "transparent": True, "depth_of_field": False,
           "motion_blur": False, "denoise": True, "tile_size": 16, "threads": 1,
           "aovs": ("depth", "objectid"), "region": (4, 4, 30, 20), "seed": 7, "progress": True,
           "extra": {"record_rays": True}}


def test_every_field_has_a_changed_value_and_metadata():
    assert set(CHANGED) == set(SETTINGS), f"list a changed value for {sorted(set(CHANGED) ^ set(SETTINGS))}"
    for name, value in CHANGED.items():
        assert value != default_of(name), name
        RenderSettings(**{name: value}).validate()
        s = SETTINGS[name]
        assert s.help, name
        assert s.flag or s.cli_from, f"{name}: neither a flag nor where the CLI takes it from"
        assert s.blender or s.blender_from, f"{name}: neither a Blender property nor where the add-on takes it from"


def _argv(name, value):
    s = SETTINGS[name]
    if isinstance(value, bool):
        return [s.flag if value else "--no-" + s.flag[2:]]
    if isinstance(value, tuple):
        return [s.flag, ",".join(value)]
    return [s.flag, str(value)]


@pytest.mark.parametrize("name", [n for n, s in SETTINGS.items() if s.flag])
def test_each_flag_reaches_render_explain_and_the_farm(name):
    from usd_io.cli import build_parser
    from usd_io.farm import UsdSource
    from usd_io.request import StageRequest, settings_from_args

    value = CHANGED[name]
    parser = build_parser()
    render_args = parser.parse_args(["render", "x.usda", "-o", "x.png", *_argv(name, value)])
    explain_args = parser.parse_args(["explain", "x.usda", "--pixel", "0", "0", *_argv(name, value)])
    for args in (render_args, explain_args):
        assert getattr(settings_from_args(args), name) == value, args.command
    source = UsdSource.of(StageRequest.from_args(render_args, "x.usda"), settings_from_args(render_args))
    assert getattr(source.tracer_settings(), name) == value
    if name in ("width", "height", "depth_of_field", "motion_blur"):  # read by the stage reader too (the size
        assert getattr(source, name) == value  # asked for; whether the camera's lens and shutter are taken)


def test_bad_flag_values_name_the_flag():
    from usd_io.cli import build_parser
    from usd_io.errors import UsdInputError
    from usd_io.request import settings_from_args

    for argv, flag in ((["--aa", "0"], "--aa"), (["--min-weight", "1"], "--min-weight"),
                       (["--epsilon", "0"], "--epsilon"), (["--tile-size", "2"], "--tile-size")):
        args = build_parser().parse_args(["render", "x.usda", "-o", "x.png", *argv])
        with pytest.raises(UsdInputError, match=flag):
            settings_from_args(args)


def test_integrator_key_holds_the_fields_its_packed_tables_read():
    """The Integrator's Options (what the kernels get as constants) and its light table are made once per session
    and settings: every setting they read must be in the key (shading once was not: the old model rendered)."""
    from tracer.integrator.wavefront import Options

    read = {n for n in Options._fields if n in SETTINGS} | {"epsilon", "shading", "light_samples"}  # eps, principled
    assert read <= set(INTEGRATOR_FIELDS), sorted(read - set(INTEGRATOR_FIELDS))
    base = RenderSettings()
    for name in INTEGRATOR_FIELDS:
        assert integrator_key(base.with_(**{name: CHANGED[name]})) != integrator_key(base), name


def test_every_blender_property_reaches_f12_settings(bpy_module):
    """Each property addon/properties.py makes from a field (no literal there) has the field's default (or the
    Blender default its Setting names: Denoise is on for F12, as in Cycles) and its value reaches the settings F12
    renders with."""
    import addon
    from addon import export

    addon.register()
    try:
        scene = bpy_module.context.scene
        props = scene.whitted
        fields = [n for n, s in SETTINGS.items() if s.blender]
        assert fields, "no Blender properties"
        defaults = export.settings_from_scene(scene)
        blender_default = lambda n: default_of(n) if SETTINGS[n].blender_default is None else SETTINGS[n].blender_default  # noqa: E731
        assert defaults.denoise is True and default_of("denoise") is False
        for name in fields:
            assert getattr(defaults, name) == blender_default(name), name
            s = SETTINGS[name]
            stored = CHANGED[name] if CHANGED[name] != blender_default(name) else default_of(name)
            setattr(props, name, stored)
            if s.toggle:  # a value under a checkbox (Noise Threshold): unticked, the field keeps its default
                assert getattr(export.settings_from_scene(scene), name) == default_of(name), name
                setattr(props, s.toggle[0], True)
            assert getattr(export.settings_from_scene(scene), name) == pytest.approx(stored), name
            setattr(props, name, s.none_as if blender_default(name) is None else blender_default(name))
            if s.toggle:
                setattr(props, s.toggle[0], False)
        assert dataclasses.asdict(export.settings_from_scene(scene)) == dataclasses.asdict(defaults)
    finally:
        addon.unregister()


def test_every_request_field_reaches_load_stage_on_a_worker_too(monkeypatch):
    """StageRequest is built once and handed on whole: each field (given a marker value) reaches load_stage from
    a local read and from the farm's UsdSource, whose own names never shadow a field."""
    import usd_io.reader
    from usd_io import farm
    from usd_io.request import StageRequest

    names = [f.name for f in dataclasses.fields(StageRequest) if f.name != "path"]
    methods = {n for n, v in vars(farm.UsdSource).items() if callable(v) or isinstance(v, (property, classmethod))}
    assert not methods & set(names), methods & set(names)
    marked = StageRequest(path="x.usda", **{n: f"<{n}>" for n in names})
    seen = []
    monkeypatch.setattr(usd_io.reader, "load_stage", lambda stage, **kw: seen.append(kw) or (None, None))
    monkeypatch.setattr(farm, "_open", lambda path: path)
    marked.read()
    farm.UsdSource.of(marked, RenderSettings()).at("<time>").read()
    for kw in seen:
        assert kw == {n: f"<{n}>" for n in names}


def test_every_blender_setting_is_drawn_in_a_panel():
    """A setting with a Blender property names the panel heading addon/ui.py draws it under (else it would exist
    but never show)."""
    pytest.importorskip("bpy")
    from addon import ui

    for name, s in SETTINGS.items():
        if s.blender:
            assert s.panel in ui.HEADINGS, name


def test_noise_threshold_is_a_checkbox_and_a_value_as_in_cycles(bpy_module):
    """Render Properties → Sampling → Noise Threshold: Cycles' checkbox (``use_adaptive_sampling``) and value
    (starting at Cycles' 0.01); unticked, F12 samples every pixel fully; Min Samples reaches F12 as it is."""
    import addon
    from addon import export

    addon.register()
    try:
        scene = bpy_module.context.scene
        props = scene.whitted
        assert props.use_adaptive_sampling is False
        assert props.adaptive_threshold == pytest.approx(0.01)
        assert export.settings_from_scene(scene).adaptive_threshold == 0.0
        props.use_adaptive_sampling = True
        props.adaptive_min_samples = 12
        got = export.settings_from_scene(scene)
        assert got.adaptive_threshold == pytest.approx(0.01) and got.adaptive_min_samples == 12

        class Layout:  # records what the Sampling panel draws, and what it greys out
            drawn: list = []

            def row(self, **kw):
                return self

            def prop(self, holder, name, **kw):
                self.drawn.append((name, getattr(self, "active", True)))

        from addon import ui

        ui.draw_settings(Layout(), props, "Sampling")
        names = [n for n, _ in Layout.drawn]
        assert names[:4] == ["samples", "use_adaptive_sampling", "adaptive_threshold", "adaptive_min_samples"], names
        props.use_adaptive_sampling = False
        props.adaptive_min_samples = 0
        Layout.drawn.clear()
        ui.draw_settings(Layout(), props, "Sampling")
        assert ("adaptive_min_samples", False) in Layout.drawn  # greyed out with the checkbox unticked
    finally:
        addon.unregister()

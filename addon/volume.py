"""A material's Volume output -> a homogeneous medium: per-channel extinction σ (1/m) and emission E (radiance per
metre), read as constants the way Cycles' SVM sets them up (``kernel/svm/closure.h``):

    Volume Absorption   σ += (1 − Color)·Density
    Volume Scatter      σ += Color·Density      (its in-scattered light is not rendered: one warning)
    Principled Volume   σ += (Color + (1 − Color)·(1 − √Absorption Color))·Density, scatter Color·Density (warned);
                        E += Emission Strength·Emission Color (Blackbody: warned, not added)
    Emission            E += Color·Strength
    Add Shader          the sum; Mix Shader (1 − Fac)·A + Fac·B

Node groups, reroutes and muted nodes are followed; a linked value other than through a group boundary is read as
the socket's own value (one warning). The tracer attenuates a ray that leaves such an object through its back face
by exp(−σ·t) over the length t it travelled inside and adds E/σ·(1 − exp(−σ·t)) (E·t where σ = 0): Beer–Lambert
with emission for a ray that entered through the front (``tracer.Scene.material_volumes``).
"""

from __future__ import annotations

import numpy as np

from .shader_tree import output_node

_ZERO = np.zeros(3)


def _colour(v) -> np.ndarray:
    try:
        return np.asarray(tuple(v)[:3], np.float64)
    except TypeError:
        return np.full(3, float(v))


class _Walker:
    def __init__(self, label: str, warn):
        self.label = label
        self._warn = warn
        self._said: set = set()

    def warn(self, key: str, message: str) -> None:
        if key not in self._said:
            self._said.add(key)
            self._warn(f"{self.label}: {message}")

    def value(self, sock, ctx: tuple):
        """The constant arriving at input ``sock`` (group inputs followed outwards), else its own value."""
        link = next((lk for lk in sock.links if lk.is_valid and not lk.is_muted), None) if sock.is_linked else None
        if link is None:
            return sock.default_value if hasattr(sock, "default_value") else 0.0
        node, out = link.from_node, link.from_socket
        while node.bl_idname == "NodeReroute":
            return self.value(node.inputs[0], ctx)
        if node.bl_idname == "NodeGroupInput" and ctx:
            outer = next((s for s in ctx[-1].inputs if s.identifier == out.identifier), None)
            if outer is not None:
                return self.value(outer, ctx[:-1])
        if node.bl_idname in ("ShaderNodeValue", "ShaderNodeRGB"):
            return out.default_value
        self.warn(f"link:{node.name}", f"the volume's {sock.name} is linked from {node.name!r}; its socket value "
                                       "is used (volumes are read as constants)")
        return sock.default_value if hasattr(sock, "default_value") else 0.0

    def closure(self, sock, ctx: tuple) -> tuple[np.ndarray, np.ndarray]:
        """(σ, E) of the closure arriving at shader input ``sock``."""
        link = next((lk for lk in sock.links if lk.is_valid and not lk.is_muted), None) if sock.is_linked else None
        if link is None:
            return _ZERO, _ZERO
        node, out = link.from_node, link.from_socket
        if node.bl_idname == "NodeReroute":
            return self.closure(node.inputs[0], ctx)
        if node.bl_idname == "NodeGroupInput":
            if not ctx:
                return _ZERO, _ZERO
            outer = next((s for s in ctx[-1].inputs if s.identifier == out.identifier), None)
            return (_ZERO, _ZERO) if outer is None else self.closure(outer, ctx[:-1])
        if node.mute:
            inner = next((il.from_socket for il in node.internal_links if il.to_socket == out), None)
            return (_ZERO, _ZERO) if inner is None else self.closure(inner, ctx)
        kind = node.bl_idname
        if kind == "ShaderNodeGroup":
            tree = node.node_tree
            outs = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"] if tree else []
            gout = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
            inner = None if gout is None else next((s for s in gout.inputs if s.identifier == out.identifier), None)
            return (_ZERO, _ZERO) if inner is None else self.closure(inner, ctx + (node,))
        if kind == "ShaderNodeAddShader":
            a, b = self.closure(node.inputs[0], ctx), self.closure(node.inputs[1], ctx)
            return a[0] + b[0], a[1] + b[1]
        if kind == "ShaderNodeMixShader":
            f = min(max(float(self.value(node.inputs[0], ctx)), 0.0), 1.0)
            a, b = self.closure(node.inputs[1], ctx), self.closure(node.inputs[2], ctx)
            return (1 - f) * a[0] + f * b[0], (1 - f) * a[1] + f * b[1]
        if kind == "ShaderNodeVolumeAbsorption":
            c = _colour(self.value(node.inputs["Color"], ctx))
            d = max(float(self.value(node.inputs["Density"], ctx)), 0.0)
            return (1.0 - c) * d, _ZERO
        if kind == "ShaderNodeVolumeScatter":
            c = _colour(self.value(node.inputs["Color"], ctx))
            d = max(float(self.value(node.inputs["Density"], ctx)), 0.0)
            self.warn("scatter", f"Volume Scatter {node.name!r}: its extinction is rendered, the light it scatters "
                                 "is not (a Whitted tracer has no volume scattering)")
            return c * d, _ZERO
        if kind == "ShaderNodeVolumePrincipled":
            c = _colour(self.value(node.inputs["Color"], ctx))
            d = max(float(self.value(node.inputs["Density"], ctx)), 0.0)
            ac = np.sqrt(np.maximum(_colour(self.value(node.inputs["Absorption Color"], ctx)), 0.0))
            sigma = (c + np.maximum(1.0 - c, 0.0) * np.maximum(1.0 - ac, 0.0)) * d
            if d > 0 and np.any(c > 0):
                self.warn("pscatter", f"Principled Volume {node.name!r}: its extinction and emission are rendered, "
                                      "the light it scatters is not")
            e = float(self.value(node.inputs["Emission Strength"], ctx)) * \
                _colour(self.value(node.inputs["Emission Color"], ctx))
            if float(self.value(node.inputs["Blackbody Intensity"], ctx)) > 0:
                self.warn("blackbody", f"Principled Volume {node.name!r}: Blackbody emission is not rendered")
            return sigma, np.maximum(e, 0.0)
        if kind == "ShaderNodeEmission":
            e = _colour(self.value(node.inputs["Color"], ctx)) * float(self.value(node.inputs["Strength"], ctx))
            return _ZERO, np.maximum(e, 0.0)
        self.warn(f"node:{node.name}", f"node {node.name!r} ({kind}) in the Volume output is not supported; "
                                       "it adds no medium")
        return _ZERO, _ZERO


def volume_of(material, warn) -> np.ndarray | None:
    """(6,) float32 = (σ RGB, E RGB) of a material's Volume output for Cycles, or None when it has none."""
    tree = getattr(material, "node_tree", None)
    if tree is None:
        return None
    out = output_node(tree)
    if out is None or "Volume" not in out.inputs or not out.inputs["Volume"].is_linked:
        return None
    sigma, emission = _Walker(f"material {material.name!r}", warn).closure(out.inputs["Volume"], ())
    if not (np.any(sigma > 0) or np.any(emission > 0)):
        return None
    return np.concatenate([sigma, emission]).astype(np.float32)


__all__ = ["volume_of"]

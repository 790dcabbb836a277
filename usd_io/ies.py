"""IES LM-63 photometric files (1986, 1991, 1995, 2002 and 2019 headers) -> a light's angular intensity table.

The file: keyword lines up to ``TILT=``, then (after a TILT=INCLUDE's tilt block) the numbers, whitespace-separated
over any number of lines: lamp count, lumens per lamp, candela multiplier, the numbers of vertical and horizontal
angles, the photometric type, units, the luminous opening's width, length and height; ballast factor, a future-use
(or ballast-lamp photometric) factor, input watts; the vertical angles, the horizontal angles, and the candela values,
one run of vertical values per horizontal angle.

Type C photometry (the usual one, and the only one UsdLux and Arnold read): the vertical angle θ is measured from the
luminaire's nadir — the light's emission axis, its −Z — and the horizontal angle φ about it from the C0 plane (the
light's +X) towards C90 (its +Y). The horizontal angles also say the symmetry: one angle, symmetric about the axis;
0–90, symmetric in each quadrant; 0–180, bilateral about the C0–C180 plane; 0–360, none.

:func:`read_ies` returns the candela values resampled to a regular (φ, θ) grid, which the tracer looks up bilinearly
(``tracer.lights.emitters.PointLight.profile``)."""

from __future__ import annotations

import numpy as np

#: The table's resolution: 1° in θ over [0°, 180°] and 2.5° in φ over [0°, 360°].
N_THETA, N_PHI = 181, 145


def parse_ies(text: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """(vertical angles °, horizontal angles °, candela (H, V) × the multiplier, photometric type) of an LM-63
    text; ValueError for a malformed one."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.strip().upper().startswith("TILT="):
            tilt = line.strip()[5:].strip().upper()
            rest = " ".join(lines[i + 1:]).split()
            break
    else:
        raise ValueError("no TILT= line (not an IES LM-63 file)")
    try:
        nums = [float(x) for x in rest]
    except ValueError as exc:
        raise ValueError(f"a non-numeric value after TILT ({exc})") from None
    if tilt == "INCLUDE":  # lamp-to-luminaire geometry, n tilt angles and n factors: not part of the distribution
        n = int(nums[1])
        nums = nums[2 + 2 * n:]
    if len(nums) < 13:
        raise ValueError("too few numbers after TILT")
    multiplier, n_v, n_h, ptype = nums[2], int(nums[3]), int(nums[4]), int(nums[5])
    body = nums[13:]
    if n_v < 1 or n_h < 1 or len(body) < n_v + n_h + n_v * n_h:
        raise ValueError(f"{n_v} vertical × {n_h} horizontal angles but {len(body)} numbers")
    v = np.asarray(body[:n_v], np.float64)
    h = np.asarray(body[n_v:n_v + n_h], np.float64)
    cd = np.asarray(body[n_v + n_h:n_v + n_h + n_v * n_h], np.float64).reshape(n_h, n_v) * multiplier
    return v, h, np.clip(cd, 0.0, None), ptype


def _full_circle(h: np.ndarray, cd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The horizontal angles and values unfolded to 0..360° by the file's symmetry."""
    if len(h) == 1:
        return np.array([0.0, 360.0]), np.vstack([cd, cd])
    last = h[-1]
    if last <= 90.0 + 1e-6:  # one quadrant, mirrored into the other three
        h = np.concatenate([h, 180.0 - h[::-1][1:]])
        cd = np.vstack([cd, cd[::-1][1:]])
        last = 180.0
    if last <= 180.0 + 1e-6:  # a half, mirrored about the C0–C180 plane
        h = np.concatenate([h, 360.0 - h[::-1][1:]])
        cd = np.vstack([cd, cd[::-1][1:]])
    if h[-1] < 360.0 - 1e-6:  # wrap
        h = np.append(h, 360.0)
        cd = np.vstack([cd, cd[:1]])
    return h, cd


def resample(v, h, cd) -> np.ndarray:
    """(N_PHI, N_THETA) candela on the regular grid φ = 0..360°, θ = 0..180° (0 outside the file's vertical range)."""
    h, cd = _full_circle(np.asarray(h, np.float64), np.asarray(cd, np.float64))
    theta = np.linspace(0.0, 180.0, N_THETA)
    phi = np.linspace(0.0, 360.0, N_PHI)
    by_h = np.stack([np.interp(theta, v, row, left=0.0, right=0.0) if len(v) > 1
                     else np.where(np.isclose(theta, v[0]), row[0], 0.0) for row in cd])  # (H', N_THETA)
    out = np.empty((N_PHI, N_THETA))
    for k in range(N_THETA):
        out[:, k] = np.interp(phi, h, by_h[:, k])
    return out


def read_ies(path: str) -> np.ndarray:
    """The (N_PHI, N_THETA) candela table of an IES file (type C); ValueError for a file that cannot be read."""
    try:
        with open(path, encoding="latin-1") as f:
            text = f.read()
    except OSError as exc:
        raise ValueError(f"cannot read {path}: {exc.strerror}") from None
    v, h, cd, ptype = parse_ies(text)
    if ptype != 1:
        raise ValueError(f"photometric type {ptype} (only type C, 1, is read)")
    table = resample(v, h, cd)
    if not np.isfinite(table).all() or table.max() <= 0:
        raise ValueError("no positive candela value")
    return table


def solid_angle_mean(table: np.ndarray) -> float:
    """The table's mean over the sphere, ∫ I dω / 4π (trapezoids in θ, weighted by sin θ)."""
    theta = np.radians(np.linspace(0.0, 180.0, table.shape[1]))
    per_theta = table[:-1].mean(axis=0)  # the φ samples, without the repeated 360°
    f = per_theta * np.sin(theta)
    return float(np.sum((f[1:] + f[:-1]) * np.diff(theta)) / 4.0)

"""
Mellor T-equivalent blocks for cylindrical parts, sliced axially.

Source: P. H. Mellor, D. Roberts, D. R. Turner, "Lumped parameter thermal
model for electrical machines of TEFC design", IEE Proc. B 138(5), 1991.
A hollow cylinder (outer radius r1, inner radius r2, length L) with uniform
heat generation is represented by two independent T-networks meeting at the
mean-temperature node, which carries the heat capacity and the loss:

- axial: face 1 --R1-- ja --R2-- face 2, ja --R3-- mean;
- radial: outer --R4-- jr --R5-- inner, jr --R6-- mean.

R3 and R6 are negative: they make the mean-node temperature equal to the true
volume-mean temperature for any surface temperatures. Validity: radial and
axial heat flows are assumed independent (superposed), properties uniform,
generation uniform within the block.
"""

from dataclasses import dataclass
from typing import List, NamedTuple, Optional, Sequence

import numpy as np

from .network import ThermalNetwork


class MellorResistances(NamedTuple):
    """The six resistances (K/W) of one Mellor block; R5 is inf for a solid cylinder."""

    R1: float
    R2: float
    R3: float
    R4: float
    R5: float
    R6: float


def mellor_resistances(r_outer_m: float, r_inner_m: float, length_m: float,
                       k_radial_W_mK: float, k_axial_W_mK: float,
                       angular_fraction: float = 1.0) -> MellorResistances:
    """
    Return the Mellor T-block resistances of a hollow (or solid, r_inner = 0) cylinder.

    ``angular_fraction`` < 1 models a sector (teeth, slots) as that share of
    the full annulus: every path area, and so every conductance, scales with it.

    Examples
    --------
    Hand-checked against conduction solutions. Hollow cylinder r1 50 mm,
    r2 20 mm, L 0.1 m, k 2 W/(m K): the radial path is the plain cylindrical
    wall, R4 + R5 = ln(r1/r2) / (2 pi k L) = 0.91629 / 1.25664 = 0.7292 K/W.

    >>> R = mellor_resistances(0.05, 0.02, 0.1, 2.0, 2.0)
    >>> round(float(R.R4 + R.R5), 4)
    0.7292

    Solid cylinder r1 10 mm, L 0.1 m, k 10 W/(m K) with uniform generation:
    the mean lies P / (8 pi k L) above a held surface, R4 + R6 = 1 / (8 pi) =
    0.03979 K/W, and P L / (12 k A) above both held faces, R1/2 + R3 =
    0.1 / (12 * 10 * pi * 1e-4) = 2.6526 K/W.

    >>> S = mellor_resistances(0.01, 0.0, 0.1, 10.0, 10.0)
    >>> round(float(S.R4 + S.R6), 5), round(float(S.R1 / 2 + S.R3), 4)
    (0.03979, 2.6526)

    """
    r1, r2, L = r_outer_m, r_inner_m, length_m
    if not (r1 > r2 >= 0.0 and L > 0.0 and k_radial_W_mK > 0.0 and k_axial_W_mK > 0.0
            and 0.0 < angular_fraction <= 1.0):
        raise ValueError(f'invalid Mellor block: r_outer {r1}, r_inner {r2}, length {L}, '
                         f'k_r {k_radial_W_mK}, k_a {k_axial_W_mK}, fraction {angular_fraction}')
    f = angular_fraction
    area = r1 ** 2 - r2 ** 2
    R1 = L / (2.0 * np.pi * k_axial_W_mK * area) / f
    R3 = -L / (6.0 * np.pi * k_axial_W_mK * area) / f
    kr = 4.0 * np.pi * k_radial_W_mK * L * f
    if r2 == 0.0:
        # limits as r2 -> 0: r2^2 ln(r1/r2) -> 0, and there is no inner surface
        return MellorResistances(R1, R1, R3, 1.0 / kr, np.inf, -1.0 / (2.0 * kr))
    ln = np.log(r1 / r2)
    R4 = (1.0 - 2.0 * r2 ** 2 * ln / area) / kr
    R5 = (2.0 * r1 ** 2 * ln / area - 1.0) / kr
    R6 = -(r1 ** 2 + r2 ** 2 - 4.0 * r1 ** 2 * r2 ** 2 * ln / area) / (2.0 * kr * area)
    return MellorResistances(R1, R1, R3, R4, R5, R6)


@dataclass
class Cylinder:
    """Node names of a cylindrical part built from axial Mellor slices (slice i = 0..n-1)."""

    name: str
    mean: List[str]
    outer: List[str]
    inner: List[Optional[str]]
    faces: List[str]  # n + 1 axial faces: faces[0] front, faces[n] rear
    volume_m3: List[float]

    @property
    def slices(self) -> int:
        """Return the number of axial slices."""
        return len(self.mean)


def add_cylinder(net: ThermalNetwork, name: str, r_outer_m: float, r_inner_m: float,
                 slice_lengths_m: Sequence[float], k_radial_W_mK: float,
                 k_axial_W_mK: float, volumetric_heat_capacity_J_m3K: float,
                 angular_fraction: float = 1.0, outer: Optional[List[str]] = None,
                 front_face: Optional[str] = None, rear_face: Optional[str] = None) -> Cylinder:
    """
    Add a cylindrical part of axial Mellor slices to ``net`` and return its node names.

    Node names: ``{name}.s{i}`` the mean node of slice i (1-based), with
    ``.outer``, ``.inner``, ``.jr``, ``.ja`` suffixes for its surfaces and
    junctions, and ``{name}.f{j}`` (j = 0..n) for the axial faces shared
    between slices. Surfaces left unconnected are adiabatic. Parts in perfect
    thermal contact share nodes: ``outer`` reuses existing outer-surface
    nodes (one per slice), ``front_face``/``rear_face`` existing face nodes.
    """
    n = len(slice_lengths_m)
    faces = [net.add_node(f'{name}.f{j}') if not ((j == 0 and front_face) or
                                                  (j == n and rear_face))
             else (front_face if j == 0 else rear_face) for j in range(n + 1)]
    mean, outer_nodes, inner, volumes = [], [], [], []
    for i, L in enumerate(slice_lengths_m):
        R = mellor_resistances(r_outer_m, r_inner_m, L, k_radial_W_mK, k_axial_W_mK,
                               angular_fraction)
        vol = np.pi * (r_outer_m ** 2 - r_inner_m ** 2) * L * angular_fraction
        m = net.add_node(f'{name}.s{i + 1}', volumetric_heat_capacity_J_m3K * vol)
        ja = net.add_node(f'{m}.ja')
        jr = net.add_node(f'{m}.jr')
        o = outer[i] if outer is not None else net.add_node(f'{m}.outer')
        net.add_resistance(faces[i], ja, R.R1)
        net.add_resistance(ja, faces[i + 1], R.R2)
        net.add_resistance(ja, m, R.R3)
        net.add_resistance(o, jr, R.R4)
        net.add_resistance(jr, m, R.R6)
        if np.isfinite(R.R5):
            inn = net.add_node(f'{m}.inner')
            net.add_resistance(jr, inn, R.R5)
        else:
            inn = None
        mean.append(m)
        outer_nodes.append(o)
        inner.append(inn)
        volumes.append(vol)
    return Cylinder(name, mean, outer_nodes, inner, faces, volumes)

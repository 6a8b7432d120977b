"""The Fundamental Earthmoving Equation (FEE): the force to cut soil with a blade.

Reece (1964) wrote the resistance of a wide blade as

    F = w * (gamma g d^2 N_gamma + c d N_c + q d N_q)

with blade width w [m], cutting depth d [m], bulk density gamma [kg/m^3], cohesion c [Pa]
and surcharge pressure q [Pa]. The N factors follow McKyes (1985, "Soil Cutting and Tillage",
ch. 4) for a flat blade at rake angle beta (from horizontal), soil friction phi, soil-tool
friction delta and a failure plane at rho = pi/4 - phi/2 (Rankine passive wedge):

    D       = cos(beta + delta) + sin(beta + delta) cot(rho + phi)
    N_gamma = (cot beta + cot rho) / (2 D)
    N_c     = (1 + cot rho cot(rho + phi)) / D
    N_q     = (cot beta + cot rho) / D

The resistance is the horizontal component; the blade also feels F tan(delta) vertically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class EarthmovingFactors:
    """Dimensionless FEE factors for one blade/soil pairing."""

    n_gamma: float
    n_cohesion: float
    n_surcharge: float


def fee_factors(
    *, rake_angle_rad: float, friction_angle_rad: float, tool_friction_angle_rad: float
) -> EarthmovingFactors:
    """McKyes' N factors; raises ValueError where the wedge model has no solution."""
    beta, phi, delta = rake_angle_rad, friction_angle_rad, tool_friction_angle_rad
    rho = math.pi / 4 - phi / 2
    denominator = math.cos(beta + delta) + math.sin(beta + delta) / math.tan(rho + phi)
    if denominator <= 1e-3:
        raise ValueError(
            f"FEE: no passive wedge for rake {math.degrees(beta):.1f} deg, "
            f"friction {math.degrees(phi):.1f} deg, tool friction {math.degrees(delta):.1f} deg"
        )
    cot_beta, cot_rho = 1 / math.tan(beta), 1 / math.tan(rho)
    return EarthmovingFactors(
        n_gamma=(cot_beta + cot_rho) / (2 * denominator),
        n_cohesion=(1 + cot_rho / math.tan(rho + phi)) / denominator,
        n_surcharge=(cot_beta + cot_rho) / denominator,
    )


def cutting_force_n(
    factors: EarthmovingFactors,
    *,
    depth_m: float,
    width_m: float,
    density_kg_m3: float,
    cohesion_pa: float,
    surcharge_pa: float = 0.0,
) -> float:
    """Horizontal FEE resistance [N] of a blade cutting ``depth_m`` deep (0 if not cutting)."""
    if depth_m <= 0.0:
        return 0.0
    weight_term = density_kg_m3 * GRAVITY_M_S2 * depth_m**2 * factors.n_gamma
    cohesion_term = cohesion_pa * depth_m * factors.n_cohesion
    surcharge_term = surcharge_pa * depth_m * factors.n_surcharge
    return width_m * (weight_term + cohesion_term + surcharge_term)

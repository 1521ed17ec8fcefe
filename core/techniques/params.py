"""Parameters that several techniques share, declared once: their specs list them."""

from __future__ import annotations

from .spec import Param

__all__ = ["ENERGY_PARAM"]

#: The diffusion techniques' ``energy`` parameter (Burley, SSSS, the combined technique).
ENERGY_PARAM = Param(
    "energy",
    "Energy",
    "How much light the scattered light returns, and at which view angles",
    type=str,
    choices=(
        (
            "object",
            "Object",
            "As Cycles' method returns it: at each view angle and curvature, less what leaves through a "
            "thin object's far side, plus what comes through it",
        ),
        (
            "view",
            "View Angle",
            "The passes' light of each material, spread over the view angles as the Cycles method returns it",
        ),
        ("lambert", "Lambert", "The passes' plain diffuse light"),
    ),
)

"""Frame B of the fidelity suite's scenes as a scenes module (``SCENES``), for the suite's
reference and runner commands (``--scenes-module benchmarks.fidelity.frame_b``): every scene with
its camera and lights moved (``scenes.frame_b``). Its references, rendered once::

    nice -n 10 .venv/bin/python -m benchmarks.fidelity.references --scenes-module benchmarks.fidelity.frame_b \\
        --store benchmarks/fidelity/references_b --samples 1024
"""

from .scenes import SCENES_B as SCENES

__all__ = ["SCENES"]

"""
What the finite-element models read of the network's node names and sources.

The models are built from node names (``part.sI``, ``part.sI.outer``,
``part.fJ``), so that they follow the network's builder as long as those
names keep their meaning.
"""

import re
from typing import List, Optional, Tuple

from ..model.motor import WetMotor


def source_names(motor: WetMotor) -> List[str]:
    """Return the node of each source of ``motor.power_W``, in order."""
    return list(motor.net._source_nodes)


def split_name(name: str) -> Tuple[str, Optional[int], Optional[str]]:
    """Split a node name into (part, slice, side): 'yoke.s2.outer', 'teeth.f0', 'magnet.s1'."""
    m = re.fullmatch(r'(.+)\.s(\d+)(?:\.(outer|inner))?', name)
    if m:
        return m.group(1), int(m.group(2)), m.group(3)
    m = re.fullmatch(r'(.+)\.f(\d+)', name)
    if m:
        j = int(m.group(2))
        return m.group(1), max(j, 1), 'front' if j == 0 else 'rear'
    return name, None, None


def oil_nodes(net) -> List[str]:
    """Return the lumped oil nodes: every node an advection link feeds."""
    return [d for _, d in net._advections]

"""
The Foxglove layouts for any actuator: the shipped ones, rewritten for a namespace.

``layouts/live.json`` (the estimator's Foxglove view) and ``layouts/replay.json``
(a recording) are written for the twin's one actuator: topics under /eha and
the nodes in the root namespace. They are the templates: :func:`layout_for`
moves every topic a panel names to another prefix and names the diagnostic
statuses of nodes in another namespace
(:func:`~wet_eha_thermal.interface.status_name`), so that each actuator of a
rig PC has its layout from the one template. ``wet-eha-thermal layout``
writes one (:mod:`wet_eha_thermal.cli.layout`).

Nothing here imports ROS.
"""

import copy
import json
from pathlib import Path
import re
from typing import Optional

from wet_eha_thermal import interface

#: The shipped layouts: ``layouts/<name>.json``
NAMES = ('live', 'replay')
#: The nodes whose diagnostic statuses a layout may name
_STATUS_NODES = (interface.ESTIMATOR_NODE, interface.RECORDER_NODE, interface.RIG_NODE)
_SOURCES = Path(__file__).resolve().parents[1] / 'layouts'


def template_path(name: str) -> Path:
    """
    Return the file of the shipped layout ``name`` (live or replay).

    From the source tree, else from the package's share directory of a
    colcon install; ValueError for another name, FileNotFoundError when
    neither has it.
    """
    if name not in NAMES:
        raise ValueError(f'layout {name!r}: expected one of {", ".join(NAMES)}')
    path = _SOURCES / f'{name}.json'
    if path.is_file():
        return path
    try:
        from ament_index_python.packages import get_package_share_directory
        path = Path(get_package_share_directory('wet_eha_thermal')) / 'layouts' / f'{name}.json'
    except (ImportError, LookupError):
        pass
    if not path.is_file():
        raise FileNotFoundError(f'layout {name}: {path} not found (the layouts/ folder of '
                                'the sources or of the installed package)')
    return path


def layout_for(layout: dict, namespace: str = '/', prefix: Optional[str] = None) -> dict:
    """
    Return a copy of a shipped ``layout`` for nodes in ``namespace``.

    ``prefix``: their topics' prefix, replacing /eha (None: the namespace's,
    as ``topic_prefix`` '' gives: :func:`~wet_eha_thermal.interface.namespace_prefix`).
    Every string of the layout that is a topic or a message path under /eha
    moves under the prefix, and every status name of the twin's nodes
    (``eha_thermal_estimator: estimate``, also inside a path's filter) takes
    the namespace. The root namespace and /eha give the layout back unchanged.
    """
    prefix = interface.namespace_prefix(namespace) if prefix is None else prefix.rstrip('/')
    topic = re.compile(rf'^{re.escape(interface.PREFIX)}(?=/|$|\.)')
    status = re.compile(rf'(^|"|\')({"|".join(map(re.escape, _STATUS_NODES))}): ')

    def move(text: str) -> str:
        text = topic.sub(prefix, text)
        return status.sub(lambda m: m.group(1) + interface.status_name('', m.group(2),
                                                                       namespace), text)

    def walk(node):
        if isinstance(node, dict):
            return {k: walk(v) for k, v in node.items()}
        if isinstance(node, list):
            return [walk(v) for v in node]
        return move(node) if isinstance(node, str) else node

    return walk(copy.deepcopy(layout))


def write_layout(name: str, path: Path, namespace: str = '/', prefix: Optional[str] = None
                 ) -> Path:
    """Write the shipped layout ``name`` for ``namespace`` (and ``prefix``) to ``path``."""
    layout = json.loads(template_path(name).read_text(encoding='utf-8'))
    path = Path(path)
    path.write_text(json.dumps(layout_for(layout, namespace, prefix), indent=2) + '\n',
                    encoding='utf-8')
    return path


def where_to_get(name: str, namespace: str = '/', prefix: Optional[str] = None) -> str:
    """Return where the layout ``name`` for ``namespace`` comes from: the file, or the command."""
    if namespace.strip('/') == '' and prefix in (None, interface.PREFIX):
        return f'layouts/{name}.json'
    command = f'wet-eha-thermal layout {name} --namespace {namespace}'
    return command + (f' --topic-prefix {prefix}' if prefix is not None else '')

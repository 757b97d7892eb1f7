"""
In-process copies of a model: pickled, with the parts that never change shared, not copied.

The live outlook saves the estimator's model at every limit tick (2 Hz) and
copies it twice per linearisation (:mod:`~wet_eha_thermal.estimator.limits`),
for the forecast and for the continuous limit. A plain pickle copies all of
it: 1.15 MB on the reference rig with its winding layers, most of it
structure fixed once the model is built (the output map, which a
``deepcopy`` of the model already shares, the loss table, cached per design
by :mod:`.loss_table`, the loss constants, the configuration and the thermal
network's index arrays). :func:`save` pickles the model with those as
references to the originals (0.73 MB): on 2026-11-28, on a loaded machine,
a copy took 1.4 ms instead of 4-7 ms and a save 2.6 ms instead of 4-7 ms.
A copy then steps as a plain one (``pickle.dumps(model)``) in the limits,
the forecast and the margin: the same bits (the golden replay did not move;
what it shares is only read). Not everywhere: heated as a cold start heats
them (:class:`~wet_eha_thermal.estimator.uncertainty.Heating`, 8 steps to
600 s), five of the reference rig's 31 uncertainty copies came out up to
4e-11 K from their plain pickles' (2026-11-29; the cause is not traced). A
copy of a snapshot steps as another copy of it does, to the bit.

A :class:`Snapshot` is bytes and is loaded only in the process that saved
it; :func:`copy` also takes plain pickled bytes (``pickle.dumps(model)``).
"""

import io
import operator
import pickle
from typing import Tuple

#: dotted paths, from the model, of what never changes once it is built (read only)
SHARED = ('cfg', 'quantities', 'motor.quantities', 'motor.loss_table',
          'motor._loss_constants') + tuple(
    f'motor.net.{name}' for name in (
        'node_names', '_links', '_link_g', '_kind', '_nn', '_nbl', '_adv_n', '_adv_b', '_src',
        '_d', '_a', '_scatter', '_scatter_reduced', '_band', '_blocks', '_ends'))


class Snapshot(bytes):
    """A model pickled by :func:`save`: the bytes and the shared objects they refer to."""

    shared: Tuple[object, ...] = ()


class _Saver(pickle.Pickler):
    def __init__(self, file, shared: Tuple[object, ...]) -> None:
        super().__init__(file, pickle.HIGHEST_PROTOCOL)
        self._ids = {id(obj): k for k, obj in enumerate(shared)}

    def persistent_id(self, obj):
        return self._ids.get(id(obj))


class _Loader(pickle.Unpickler):
    def __init__(self, data: bytes, shared: Tuple[object, ...]) -> None:
        super().__init__(io.BytesIO(data))
        self._shared = shared

    def persistent_load(self, pid):
        return self._shared[pid]


def save(model) -> Snapshot:
    """Return ``model`` pickled, its unchanging parts (:data:`SHARED`) by reference."""
    shared = tuple(operator.attrgetter(path)(model) for path in SHARED)
    buf = io.BytesIO()
    _Saver(buf, shared).dump(model)
    snap = Snapshot(buf.getvalue())
    snap.shared = shared
    return snap


def copy(saved: bytes):
    """Return a new model from a :class:`Snapshot` (or from plain pickled bytes)."""
    if isinstance(saved, Snapshot):
        return _Loader(saved, saved.shared).load()
    return pickle.loads(saved)

"""
What-ifs served off the caller's thread: one worker process, one request at a time.

The estimator node must not stall its 50 Hz steps for a what-if, which
costs seconds of a core for an hour of duty. It takes a request on its own
thread, pickles the model there and then (a snapshot of the state as the
request arrived: about a millisecond and 0.6 MB; the pool would pickle it
later, on another thread, while the model steps on) and hands the bytes to
a single worker process, which parses the request, runs
:func:`~.whatif.what_if` at a lower priority than the node and returns the
answer as JSON text. A request while one runs, or before the estimator has
a state, is answered at once with an error; so is a bad request, by the
worker. Every answer is a JSON object with the request's ``id`` and ``ok``
(:func:`run_request`): an error is an answer, never an exception.

The worker is forked from a fork server (not from the node, whose ROS and
server threads a fork would copy in whatever state they are), started by
:meth:`WhatIfWorker.start` when the node starts: starting it takes most of
a second of the caller's time, and loading the model's compiled kernels
and running a few seconds of a stage (``WARM_REQUEST``) a few seconds of the
worker's, which no request should wait for (on a fresh install, where they
compile, the first what-if stalled the estimator's estimates for 0.6 s). As with any
start method but fork, the worker imports the parent's main module (not as
``__main__``): a script that starts a worker keeps its work under
``if __name__ == '__main__'``.
"""

from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
import json
import os
import pickle
import time
from typing import Optional, Sequence

from .whatif import error_answer, id_of, parse_request, RequestError, what_if
from ..config import Config
from ..model.eha import EHAModel
from ..model.warmup import compile_model
from ..processes import fork_server, stop_pool

#: How much nicer than its parent the worker runs: the estimator's steps come first.
WORKER_NICE = 10
#: Largest request (bytes of JSON): a day of samples at 1 Hz is about 5 MB.
MAX_REQUEST_BYTES = 16 * 2 ** 20


def run_request(text: str, cfg: Config, known: Sequence[str], model: Optional[bytes],
                ambient_C: float, source: str, start_stamp_s: Optional[float]) -> str:
    """
    Return the answer (strict JSON text) to the request ``text``, run from ``model``.

    ``model``: a pickled :class:`~..model.eha.EHAModel` (None: cold);
    ``known``: the quantities a request may name. Never raises: a bad
    request or a failed run is an answer with ``ok`` false and the reason.
    """
    rid = id_of(text)
    try:
        request = parse_request(text, cfg, known)
        start = pickle.loads(model) if model is not None else None
        result = what_if(cfg, request, start, ambient_C, source, start_stamp_s)
        return json.dumps(result.to_dict(), allow_nan=False)
    except RequestError as exc:
        return json.dumps(error_answer(rid, str(exc)))
    except Exception as exc:  # noqa: B902 - a what-if that fails is an answer
        return json.dumps(error_answer(rid, f'the what-if failed: {type(exc).__name__}: {exc}'))


def _lower_priority() -> None:
    """Run the worker after the node's threads (the pool's initializer)."""
    os.nice(WORKER_NICE)


#: The worker's warm-up what-if: a few steps of a reference stage from cold, so the duty's
#: and the run's kernels are loaded (or, on a fresh install, compiled) before any request
WARM_REQUEST = {'id': 'warm-up', 'stage': 6, 'duration_s': 4.0, 'record_every_s': 1.0}


def _warm_up(cfg: Config, known: Sequence[str]) -> float:
    """Load the compiled kernels a what-if runs in the worker; return the seconds it took."""
    start = time.perf_counter()
    compile_model(cfg)
    what_if(cfg, parse_request(WARM_REQUEST, cfg, known))
    return time.perf_counter() - start


class WhatIfWorker:
    """
    Run what-ifs in one worker process, one at a time; answers are polled, never waited for.

    ``cfg``: the estimator's configuration; ``known``: the quantities its
    model names.
    """

    def __init__(self, cfg: Config, known: Sequence[str]) -> None:
        self.cfg = cfg
        self.known = tuple(known)
        self._pool: Optional[ProcessPoolExecutor] = None
        self._running: Optional[Future] = None
        self._running_id = ''
        self._started = 0.0
        #: requests taken, answered with an error at once, and run
        self.requests = self.refused = self.runs = 0

    def start(self) -> None:
        """Start the worker (if it is not running) and load the model in it, in the background."""
        if self._pool is not None:
            return
        self._pool = ProcessPoolExecutor(1, mp_context=fork_server(preload=[__name__]),
                                         initializer=_lower_priority)
        # a request queues behind it in the one worker
        self._pool.submit(_warm_up, self.cfg, self.known)

    @property
    def busy(self) -> bool:
        """Tell whether a what-if runs now."""
        return self._running is not None

    def submit(self, text: str, model: Optional[EHAModel], ambient_C: float, source: str,
               start_stamp_s: Optional[float]) -> Optional[str]:
        """
        Start the what-if of ``text`` from ``model``'s state as it is now.

        Returns None when it started (its answer comes from :meth:`poll`),
        else the answer at once: busy, no state yet (``model`` None), a
        request too large.
        """
        self.requests += 1
        rid = id_of(text)
        refusal = None
        if self._running is not None:
            refusal = (f'busy: what-if {self._running_id!r} runs since '
                       f'{time.monotonic() - self._started:.1f} s; one at a time: ask again '
                       'once its answer has come')
        elif model is None:
            refusal = ('the estimator has no state yet (no samples taken): ask again once it '
                       'estimates')
        elif len(text) > MAX_REQUEST_BYTES:
            refusal = f'request of {len(text)} bytes: at most {MAX_REQUEST_BYTES} bytes'
        if refusal is not None:
            self.refused += 1
            return json.dumps(error_answer(rid, refusal))
        snapshot = pickle.dumps(model, protocol=pickle.HIGHEST_PROTOCOL)
        self.start()         # again after the worker died
        self._running = self._pool.submit(run_request, text, self.cfg, self.known, snapshot,
                                          ambient_C, source, start_stamp_s)
        self._running_id, self._started = rid, time.monotonic()
        self.runs += 1
        return None

    def poll(self) -> Optional[str]:
        """Return the answer of the what-if that finished since the last call, else None."""
        if self._running is None or not self._running.done():
            return None
        future, self._running = self._running, None
        try:
            return future.result()
        except Exception as exc:  # noqa: B902 - the worker died, or the call could not go
            if isinstance(exc, BrokenProcessPool):
                self._pool = None          # a new worker for the next request
            return json.dumps(error_answer(self._running_id, f'the what-if worker failed: '
                                           f'{type(exc).__name__}: {exc}'))

    def close(self) -> None:
        """Stop the worker, and a what-if it runs."""
        if self._pool is None:
            return
        stop_pool(self._pool)
        self._pool = None

"""The fixed-trajectory engine's compiled fast path (numba, the optional ``fast`` extra).

For a policy with a compiled twin (Greedy and HGAD, ``slot_rule``), the fixed-trajectory
engine (:mod:`skymule.sim.fixed`) runs :func:`slot_loop` compiled instead of its numpy
slot loop, and gives the same record, value for value. The numpy loop steps all B missions
one slot at a time and pays numpy's per-call overhead in every slot; here one mission runs
all its slots in registers before the next (``docs/speed-notes.md``).

The rules are not re-stated here: the loop calls the one-mission kernels of
:mod:`skymule.sim.kernels` and :func:`skymule.rules.contract.served_bits`, registered with
numba so the same Python functions run compiled. Fault draws (outages, burst loss, SNR
errors, missed polls) are applied per mission and slot as the numpy loop applies them
(:func:`skymule.sim.kernels.fault_view`). Missions with per-slot fading, and SNR errors on a
rate table other than a step table (a rate computed per slot), stay on the numpy loop
(:func:`skymule.sim.fixed.compiled_reason`).

With summaries asked for (:mod:`skymule.sim.compiled_summaries`) the loop writes no per-slot
log: it reduces each mission's slots as the mission ends
(:func:`skymule.sim.summary_kernels.mission_totals`).

Install: ``pip install skymule[fast]``. Without numba, :func:`available` is False and the
engine runs its numpy loop (the reference).
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import sys
import threading
import time
import types
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.rules import contract
from skymule.rules.contract import NO_SENSOR
from skymule.sim import kernels, summary_kernels
from skymule.sim.kernels import KernelFaults

ENGINES = ("auto", "numpy", "compiled")
"""``engine``: ``numpy`` (the slot loop in numpy, the reference), ``compiled`` (the compiled
twins: the policy's rule for Greedy/HGAD on fixed paths, the path queries on autonomous ones;
a one-line error where they cannot run) or ``auto`` (compiled where it can, else numpy)."""


def available() -> bool:
    """True if numba is installed (``pip install skymule[fast]``)."""
    return importlib.util.find_spec("numba") is not None


def check_engine(engine: str, context: str = "") -> str:
    """``engine`` if it is one of :data:`ENGINES`, else the one-line SkymuleError (its text
    prefixed with ``context``)."""
    if engine not in ENGINES:
        raise SkymuleError(f"{context}engine = {engine!r}; allowed: {', '.join(ENGINES)}")
    return engine


def no_logs() -> tuple[np.ndarray, ...]:
    """Placeholders for :func:`slot_loop`'s four (B, T) logs and the buffer log, when unused."""
    return (
        np.zeros((0, 0), np.int64),
        np.zeros((0, 0)),
        np.zeros((0, 0), np.bool_),
        np.zeros((0, 0), np.int64),
        np.zeros((0, 0, 0)),
    )


def no_totals(n_sensors: int) -> tuple[summary_kernels.SummaryTables, summary_kernels.SlotTotals]:
    """Placeholders for :func:`slot_loop`'s summary tables and totals, when unused (the same
    types as real ones, so both calls share one compiled loop)."""
    tables = summary_kernels.SummaryTables(
        steps_m=np.zeros((0, 1)),
        power_w=np.zeros((0, 1)),
        pair=np.zeros(0, np.int64),
        near=np.zeros((0, n_sensors), np.int64),
        group=np.zeros(0, np.int64),
        aadm_threshold_bit=np.zeros(0),
        aadm_window_slots=np.zeros(0),
        aadm_per_slot=False,
        width=0,
    )
    return tables, summary_kernels.new_totals(0, n_sensors)


def slot_loop(
    rate: np.ndarray,
    snr: np.ndarray,
    track_id: np.ndarray,
    n_samples: np.ndarray,
    limit: np.ndarray,
    last_sample: np.ndarray,
    n_slots: np.ndarray,
    window_slots: np.ndarray,
    slot_s: np.ndarray,
    buffers: np.ndarray,
    hgad: np.ndarray,
    threshold: np.ndarray,
    peak: np.ndarray,
    max_hover: np.ndarray,
    keep_logs: bool,
    keep_remaining: bool,
    served: np.ndarray,
    downloaded: np.ndarray,
    hovering: np.ndarray,
    sample_log: np.ndarray,
    remaining_log: np.ndarray,
    n_run: np.ndarray,
    end_sample: np.ndarray,
    left: np.ndarray,
    want_totals: bool,
    tables: summary_kernels.SummaryTables,
    totals: summary_kernels.SlotTotals,
    faults: KernelFaults | None,
    chosen: np.ndarray | None,
) -> None:
    """Every slot of every mission; fills ``n_run``, ``end_sample``, ``left`` and, as asked,
    the (B, T) logs (``keep_logs``; ``chosen`` too unless None) and each mission's summary
    reductions (``want_totals``).

    Missions with faults (``faults.fault_of[b] >= 0``) see and deliver through
    :func:`~skymule.sim.kernels.fault_view`, as the numpy loop through ``apply_faults``.
    ``faults=None`` (no mission has faults) compiles a loop without any of that: numba prunes
    the ``is not None`` branches, and the fault-free loop keeps its speed.

    Arrays are those of :class:`~skymule.sim.fixed.TrackTables` (rate and snr seen per
    track sample, per-mission parameters with thresholds and peaks as (B, N));
    ``remaining_log`` is (B, T, N)
    when ``keep_remaining``, else unused; without ``keep_logs`` the four (B, T) logs are unused
    (each mission's slots go to scratch rows, reduced by
    :func:`~skymule.sim.summary_kernels.mission_totals` while still in cache).
    Pure Python numba compiles (see :func:`compiled_loop`).
    """
    n_missions, n_sensors = buffers.shape
    t_max = 0
    for b in range(n_missions):
        t_max = max(t_max, n_slots[b])
    remaining = np.empty(n_sensors)
    cooling = np.zeros(n_sensors, np.bool_)
    hover = np.empty(2)
    final = np.zeros(n_missions, np.int64)
    # one mission's slots when no log is kept, and the reductions' scratch space
    served_row = np.empty(t_max, np.int64)
    downloaded_row = np.empty(t_max)
    hovering_row = np.empty(t_max, np.bool_)
    sample_row = np.empty(t_max, np.int64)
    scratch = np.empty((2, t_max))
    memo = np.full(4, -1.0)
    seen_rate = np.empty(n_sensors)
    seen_snr = np.empty(n_sensors)
    deliver = np.empty(n_sensors)
    steps, efficiency, bandwidth = np.empty(0), np.empty(1), 0.0  # its rate table
    for b in range(n_missions):
        if keep_logs:
            served_row, downloaded_row = served[b], downloaded[b]
            hovering_row, sample_row = hovering[b], sample_log[b]
        u = track_id[b]
        dt = slot_s[b]
        is_hgad = hgad[b]
        threshold_b, peak_b, max_hover_b = threshold[b], peak[b], max_hover[b]
        remaining[:] = buffers[b]
        cooling[:] = False
        hover[0] = NO_SENSOR
        hover[1] = 0.0
        g = -1
        if faults is not None:
            g = faults.fault_of[b]
            if g >= 0:  # this mission's track and draws, rows read by index in each slot
                ok_rows, error_rows = faults.deliverable[g], faults.snr_error_db[g]
                rate_rows, snr_rows = rate[u], snr[u]
                uses_error = faults.uses_error[g]
                model = faults.model[g]
                steps, efficiency = faults.thresholds_db[model], faults.efficiency[model]
                bandwidth = faults.bandwidth_hz[model]
        sample = 0
        run = 0
        for slot in range(n_slots[b]):
            if sample >= n_samples[b]:
                break
            rate_now = rate[u, sample]
            if faults is not None and g >= 0:  # the policy sees the faulty SNR; `deliver`
                kernels.fault_view(  # is what serving yields
                    rate_rows, snr_rows, sample, ok_rows, error_rows, slot, uses_error, steps,
                    efficiency, bandwidth, seen_rate, seen_snr, deliver,
                )  # fmt: skip
                rate_now = seen_rate
            if hover[0] >= 0:  # hovering: the hovered sensor (the choice would go unused)
                sensor = int(hover[0])
            else:
                snr_now = snr[u, sample]
                if faults is not None and g >= 0:
                    snr_now = seen_snr
                if is_hgad:
                    sensor = kernels.hgad_pick(rate_now, snr_now, remaining)
                else:
                    sensor = kernels.greedy_pick(snr_now, rate_now, remaining)
            cell = max(sensor, 0)
            before = remaining[cell]
            bits = contract.served_bits(rate_now[cell], before, dt) if sensor >= 0 else 0.0
            after = before - bits  # what the policy expects after this slot
            delivered = sensor
            if slot >= window_slots[b]:  # the download window has closed: nothing arrives
                delivered = NO_SENSOR
                bits = 0.0
            if chosen is not None and keep_logs:
                chosen[b, slot] = delivered
            if faults is not None and g >= 0:  # a fault blocks the choice: 0 bits, no sensor
                if delivered >= 0 and not ok_rows[slot, cell]:
                    delivered = NO_SENSOR
                bits = contract.served_bits(deliver[cell], before, dt) if delivered >= 0 else 0.0
            remaining[cell] = before - bits
            held = False
            if is_hgad:
                held = kernels.hgad_hover_step(
                    hover,
                    cooling,
                    sensor,
                    rate_now,
                    after,
                    threshold_b,
                    peak_b,
                    max_hover_b,
                    dt,
                    True,
                )
            served_row[slot] = delivered
            downloaded_row[slot] = bits
            hovering_row[slot] = held
            sample_row[slot] = sample
            if keep_remaining:
                remaining_log[b, slot] = remaining
            run += 1
            if not held:
                sample = min(sample + 1, limit[b])
        n_run[b] = run
        final[b] = sample
        end_sample[b] = min(sample, last_sample[b])
        left[b] = remaining
        if want_totals:
            summary_kernels.mission_totals(
                b, served_row, downloaded_row, hovering_row, sample_row, run, dt, tables,
                scratch, memo, totals,
            )  # fmt: skip
    if not keep_logs:
        return
    # the numpy loop keeps writing an ended mission's sample and buffers until every mission
    # has ended; the same padding here makes the two results equal array for array
    stop = 0
    for b in range(n_missions):
        stop = max(stop, n_run[b])
    for b in range(n_missions):
        for slot in range(n_run[b], stop):
            sample_log[b, slot] = final[b]
            if keep_remaining:
                remaining_log[b, slot] = left[b]


def jit(
    function: Callable[..., Any],
    calls: tuple[Callable[..., Any], ...],
    inline: tuple[Callable[..., Any], ...] = (),
) -> Callable[..., Any]:
    """``function`` compiled by numba, with the plain-Python functions it ``calls``; those in
    ``inline`` are also pasted into their callers (numba's ``inline="always"``).

    Inlining the per-slot choice and hover kernels makes the HGAD loop ~25 % faster (a call
    per slot costs more than these few comparisons); the kernels with running sums are not
    inlined, where numba's inliner warns about its own SSA pass.

    Cached on disk; numba's cache notices changes to ``function``'s own source only, not to
    what it calls, so the compiled copy is named after a hash of all their sources: a change
    to any rule gives a new name, hence a new cache entry, never a stale one.
    """
    import numba
    from numba.extending import register_jitable

    note_first_compile()
    for kernel in calls:
        register_jitable(inline="always" if kernel in inline else "never")(kernel)
    source = "".join(inspect.getsource(f) for f in (function, *calls))
    source += " ".join(f.__name__ for f in inline)
    name = f"{function.__name__}_{hashlib.sha256(source.encode()).hexdigest()[:12]}"
    copy = types.FunctionType(function.__code__, function.__globals__, name)
    copy.__qualname__ = name
    return numba.njit(nogil=True, cache=True)(copy)


FIRST_COMPILE_NOTE = (
    "skymule: compiling the fast engine (numba) for this installation, once (~10-20 s); "
    "later runs load it from numba's cache"
)


COMPILE_NOTE_AFTER_S = 1.0
"""A compile of a skymule kernel that lasts longer than this [s] is announced (once)."""

_COMPILE_NOTE_SAID = threading.Event()
"""Set once :data:`FIRST_COMPILE_NOTE` has been printed in this process."""
_COMPILE_NOTE_LOCK = threading.Lock()


def _launched_here() -> bool:
    """True in the process the user started; False in a worker it started (a process pool's
    or dask-local's), whose piped stderr is the user's too: a worker says it on a terminal
    only, so N workers compiling at once do not add N lines to a piped log."""
    import multiprocessing

    return multiprocessing.parent_process() is None


@cache
def note_first_compile() -> None:
    """Once per process: when numba compiles a skymule kernel (its compile event fires on a
    cache miss only: a new installation, a changed rule, a new signature) for longer than
    :data:`COMPILE_NOTE_AFTER_S`, print :data:`FIRST_COMPILE_NOTE` on stderr, terminal or
    pipe alike (a worker process: on a terminal only, see :func:`_launched_here`), so a first
    run's pause is explained; a quick compile says nothing. The line comes while the compile
    runs (a timer), or as it ends if the timer could not run."""
    from numba.core import event

    class FirstCompileNote(event.Listener):
        def __init__(self) -> None:
            self.depth = 0  # compiles nest (a kernel compiles the kernels it calls)
            self.started = 0.0
            self.timer: threading.Timer | None = None

        def say(self) -> None:
            with _COMPILE_NOTE_LOCK:
                if _COMPILE_NOTE_SAID.is_set():
                    return
                _COMPILE_NOTE_SAID.set()
            if _launched_here() or sys.stderr.isatty():
                print(FIRST_COMPILE_NOTE, file=sys.stderr, flush=True)

        def on_start(self, happened: event.Event) -> None:
            function = getattr(happened.data.get("dispatcher"), "py_func", None)
            ours = getattr(function, "__module__", "").startswith("skymule.")
            if _COMPILE_NOTE_SAID.is_set() or (self.depth == 0 and not ours):
                return
            self.depth += 1
            if self.depth == 1:
                self.started = time.perf_counter()
                self.timer = threading.Timer(COMPILE_NOTE_AFTER_S, self.say)
                self.timer.daemon = True
                self.timer.start()

        def on_end(self, happened: event.Event) -> None:
            if self.depth == 0:
                return
            self.depth -= 1
            if self.depth == 0 and self.timer is not None:
                self.timer.cancel()
                if time.perf_counter() - self.started > COMPILE_NOTE_AFTER_S:
                    self.say()

    event.register("numba:compile", FirstCompileNote())


@cache
def compiled_loop() -> Callable[..., None]:
    """:func:`slot_loop` compiled (once per process; cached on disk, see :func:`jit`)."""
    choose = (kernels.greedy_pick, kernels.hgad_pick, kernels.hgad_hover_step, kernels.fault_view)
    return jit(
        slot_loop,
        (
            contract.served_bits,
            *choose,
            kernels.step_rate,
            summary_kernels.slots_before,
            summary_kernels.mission_totals,
        ),
        inline=choose,
    )


@cache
def compiled_reduce() -> Callable[..., None]:
    """:func:`~skymule.sim.summary_kernels.reduce_rows` compiled (a pass over logs kept, or
    over an autonomous batch's arrays)."""
    return jit(
        summary_kernels.reduce_rows,
        (
            summary_kernels.slots_before,
            summary_kernels.mission_totals,
            summary_kernels.first_target_arrivals,
        ),
    )

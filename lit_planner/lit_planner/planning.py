"""The planner's Python API: a scenario becomes a query, a policy name becomes a policy, and
:func:`plan` runs one planner on one scenario and returns everything it reported.

::

    from lit_planner.planning import plan
    result = plan("np8", planner="litstar", policy="fixed", time=0.4, seed=1)
    result["solved"], result["cost"], result["path_check"]["ok"]

The C++ core (``lit_core``) does the planning; this module only translates names into core
objects and adds what the core cannot know: the scenario's identity and optimum, and an
independent numpy re-check of the returned path (:func:`lit_planner.scenarios.check_path`).

Results keep the core's floats, so an unsolved run has ``cost``, ``t_init`` and ``c_init`` equal to
``inf``. :func:`json_safe` turns a result into JSON-able data with ``null`` for every
non-finite float (JSON has no infinity).
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
import os
import re
import threading
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import lit_core

from lit_planner import scenarios
from lit_planner.errors import MissingTensorsError, PlannerError, TensorFileError
from lit_planner.scenarios import Scenario

LITSTAR = "litstar"
"""Our planner; the only one that takes a parameter policy."""
OMPL_PLANNERS = ("aitstar", "bitstar", "abitstar", "irrtstar", "rrtconnect")
"""OMPL 1.5.2's planners that the core runs on the same problem and validity checker."""
PLANNERS = (LITSTAR, *OMPL_PLANNERS)
"""Planner names of the core."""
POLICIES = ("fixed", "fit", "tensor", "external")
"""Policy names :func:`make_policy` knows."""
NAMED_POLICIES = ("fixed", "fit", "tensor")
"""Policies that a name alone configures (``external`` needs a callable)."""
DEFAULT_POLICY = "fixed"
"""LIT*'s policy when none is given: B = 100, psi_K = e (our EIT* baseline)."""
SHORTHANDS = {f"{LITSTAR}-{policy}": policy for policy in NAMED_POLICIES}
"""``litstar-fixed``, ``litstar-fit``, ``litstar-tensor``: LIT* with that policy, as one name."""
PLANNER_CHOICES = (*PLANNERS, *SHORTHANDS)
"""Every planner name :func:`plan` and ``lit plan --planner`` accept."""
INTERPOLATIONS = {
    "trilinear": lit_core.Interpolation.trilinear,
    "nearest": lit_core.Interpolation.nearest,
}
"""Lookup modes of the ``tensor`` policy."""
TENSORS_ENV = "LIT_TENSORS"
"""Environment variable that overrides the default tensor folder."""
TENSOR_FILES = {"B": "b_tensor.npy", "psi_K": "k_tensor.npy"}
"""File name of each output's lookup tensor inside a tensor folder (sidecars: same stem, .json)."""
MAX_SEED = 2**32 - 1
"""Largest seed the core accepts (an unsigned 32-bit integer)."""
MAX_DECISION_INTERVAL = 2**32 - 1
"""Most expansions per psi_K decision the core accepts (an unsigned 32-bit integer)."""
_ARGUMENT_PARAMS = {
    "seed": "seed",
    "time_budget": "time",
    "policy": "policy",
    "max_iterations": "max_iterations",
    "max_batches": "max_batches",
}
"""Planner parameters that :func:`plan` sets from its own arguments."""
MAX_TIME = 1e9
"""Longest planning time, s (about 32 years): OMPL's time-based stop counts nanoseconds in 64
bits, and from about 9.2e9 s on it overflowed, so OMPL's planners stopped at once (timeout)."""


MIN_TIME = 1e-6
"""Shortest time budget a scale factor (``lit bench --time-scale``, ``lit train --budget-scale``)
may make of a scenario's, s: a rule of these commands, not of the planner (which takes any
positive time), against a mistyped factor (1e-320 made a budget 0, or a denormal the
benchmark's time grid could not start from, after every run had been planned)."""


def scale_problem(option: str, scale: float, longest: float, shortest: float) -> str | None:
    """What is wrong with the time budgets of ``shortest`` to ``longest`` s scaled by ``scale``
    (the value of the command's ``option``), or None: a scaled budget must be one a planner can
    be given (:data:`MAX_TIME`) and not below :data:`MIN_TIME`."""
    if longest * scale > MAX_TIME:
        return (
            f"{option} {scale:g} gives budgets up to {longest * scale:g} s, more than the "
            f"{MAX_TIME:g} s a planner can be given"
        )
    if shortest > 0 and shortest * scale < MIN_TIME:
        return (
            f"{option} {scale:g} gives budgets down to {shortest * scale:g} s, less than the "
            f"{MIN_TIME:g} s {option} allows"
        )
    return None


DecisionCallback = Callable[[lit_core.DecisionContext], float]


def default_tensors_dir() -> Path:
    """Where the ``tensor`` policy looks: ``$LIT_TENSORS``, else the checkout's ``tensors/``."""
    override = os.environ.get(TENSORS_ENV)
    if override:
        return Path(override)
    return Path(__file__).resolve().parents[2] / "tensors"


_CORE_ARGUMENT_ERROR = re.compile(
    r"planner \S+ (has no parameter|rejected the value)|policies apply to|\S+ stops on time only"
    r"|solve needs a (positive|finite) time|unknown planner"
)
"""The messages of ``lit_core.solve``'s own argument checks (python/bindings.cpp)."""


def query_for(scenario: Scenario | str) -> lit_core.Query:
    """The core's query for ``scenario`` (or the registry's scenario of that name): its bounds,
    boxes, start, goal and resolution; a custom world's edges are checked exactly against its
    boxes (the registry's scenarios keep the discrete checks at their resolution, the same for
    every planner, as PDT's benchmarks do).

    Raises:
        ScenarioError: an unknown scenario name.
    """
    if not isinstance(scenario, Scenario):
        scenario = scenarios.get(scenario)  # a name, or an error naming what was given
    return lit_core.Query(
        list(scenario.lower),
        list(scenario.upper),
        scenario.boxes[:, 0, :].tolist(),
        scenario.boxes[:, 1, :].tolist(),
        list(scenario.start),
        list(scenario.goal),
        scenario.resolution,
        exact_edges=scenario.family == scenarios.CUSTOM_FAMILY,
    )


def check_count(value: object, label: str) -> None:
    """Refuse an iteration or batch limit that LIT* cannot take (``label`` names it in the
    message: the argument, or a command's option).

    Raises:
        PlannerError: not a whole number in 0 (no limit) .. :data:`MAX_SEED`.
    """
    if not _is_whole(value) or not 0 <= value <= MAX_SEED:
        raise PlannerError(
            f"{label} must be a whole number between 0 (no limit) and {MAX_SEED}, got {value!r}"
        )


def check_stops_on_count(core_planner: str, stops_on_count: bool) -> None:
    """PlannerError when an iteration or batch limit is given to a planner other than LIT*."""
    if core_planner != LITSTAR and stops_on_count:
        raise PlannerError(
            f"{core_planner} stops on time only: max_iterations and max_batches are for {LITSTAR}"
        )


def check_seed_in_node(core_planner: str, seeded: bool) -> None:
    """PlannerError when a plan request to the planner node gives a seed to a planner other than
    LIT*: the node answered it as the seed used, and two plans of one seed differed."""
    if core_planner != LITSTAR and seeded:
        raise PlannerError(
            f"{core_planner} cannot take a seed in the planner node: OMPL's planners draw from "
            "OMPL's generator, which a process seeds once, so the node cannot repeat their plans "
            "(`lit plan` can: a process of its own); leave the seed out"
        )


def resolve_planner(planner: str, policy: str | None = None) -> tuple[str, str | None]:
    """Split a planner name (shorthands included) into the core's planner and the policy name.

    Returns:
        ``(core planner, policy)``; the policy is :data:`DEFAULT_POLICY` for LIT* when none is
        given, and None for the OMPL planners.

    Raises:
        PlannerError: unknown planner, unknown policy, a policy for an OMPL planner, or a
            shorthand contradicting ``policy``.
    """
    if planner in SHORTHANDS:
        implied = SHORTHANDS[planner]
        if policy is not None and policy != implied:
            raise PlannerError(
                f"planner {planner!r} means policy {implied!r}, but policy {policy!r} was given"
            )
        return LITSTAR, implied
    if planner == LITSTAR:
        chosen = DEFAULT_POLICY if policy is None else policy
        if chosen not in POLICIES:
            raise PlannerError(f"unknown policy {chosen!r}; expected one of {', '.join(POLICIES)}")
        return LITSTAR, chosen
    if planner in OMPL_PLANNERS:
        if policy is not None:
            raise PlannerError(
                f"policy {policy!r} applies to {LITSTAR} only; {planner} has no parameter policy"
            )
        return planner, None
    raise PlannerError(f"unknown planner {planner!r}; expected one of {', '.join(PLANNER_CHOICES)}")


def make_policy(
    name: str,
    tensors_dir: Path | str | None = None,
    interpolation: str | None = None,
    callback: DecisionCallback | None = None,
) -> lit_core.ParameterPolicy:
    """The core's parameter policy called ``name``.

    Args:
        name: ``fixed`` (B = 100, psi_K = e), ``fit`` (FIT*'s batch rule), ``tensor`` (the
            trained lookup tensors) or ``external`` (``callback`` decides).
        tensors_dir: folder holding ``b_tensor.npy`` and/or ``k_tensor.npy`` with their sidecars
            (``tensor`` only); :func:`default_tensors_dir` when None. A missing tensor makes that
            parameter fall back to its fixed value. The policy's ``decision_interval`` is the
            psi_K tensor's training interval (:func:`trained_decision_interval`), which
            :func:`plan` applies.
        interpolation: ``trilinear`` or ``nearest`` lookup (``tensor`` only); None: the mode
            the tensors' sidecars name (``lit train`` exports name ``trilinear``).
        callback: ``callback(context: lit_core.DecisionContext) -> float`` answering B or psi_K
            (``external`` only). The planner's clock is paused while it runs; an answer that is
            NaN or raises falls back to the fixed value and is counted in the policy's
            ``failures``.

    Raises:
        PlannerError: unknown name or interpolation, a callback missing / given in vain, or
            ``tensors_dir`` / ``interpolation`` for a policy other than ``tensor``.
        MissingTensorsError: ``tensor`` found neither tensor file.
        TensorFileError: a tensor file or its sidecar is defective (names the file and problem).
    """
    if name not in POLICIES:
        raise PlannerError(f"unknown policy {name!r}; expected one of {', '.join(POLICIES)}")
    if (callback is not None) != (name == "external"):
        raise PlannerError(
            "the external policy needs a callback"
            if callback is None
            else f"a callback applies to the external policy only, not to {name!r}"
        )
    if name != "tensor" and (tensors_dir is not None or interpolation is not None):
        raise PlannerError(
            f"tensors_dir and interpolation are for the tensor policy, not for {name!r}"
        )
    if name == "fixed":
        return lit_core.FixedPolicy()
    if name == "fit":
        return lit_core.FitPolicy()
    if name == "external":
        if not callable(callback):
            raise PlannerError(f"the external policy's callback {callback!r} is not callable")
        return lit_core.ExternalPolicy(callback)
    if interpolation is not None and interpolation not in INTERPOLATIONS:
        raise PlannerError(
            f"unknown interpolation {interpolation!r}; expected one of {', '.join(INTERPOLATIONS)}"
        )
    folder = default_tensors_dir() if tensors_dir is None else Path(tensors_dir)
    if folder.exists() and not folder.is_dir():
        raise TensorFileError(
            f"{folder}: a file; the tensor policy needs the folder of the tensors"
        )
    from lit_planner import tensor_files

    # A tensor counts as present when its data or its sidecar is: one without the other (a
    # half-deleted pair) is a defect to report, not a tensor to leave out silently.
    tensors = {
        output: load_tensor(folder / file_name, output)
        for output, file_name in TENSOR_FILES.items()
        if (folder / file_name).exists() or tensor_files.sidecar_path(folder / file_name).exists()
    }
    if not tensors:
        if tensors_dir is not None:
            source = "given"
        elif os.environ.get(TENSORS_ENV):
            source = f"from ${TENSORS_ENV}"
        else:
            source = f"the default; set ${TENSORS_ENV} or pass a folder to override"
        try:
            where = "" if folder.exists() else "; the folder does not exist"
        except OSError:  # a parent that cannot be read: said by the name of the folder
            where = ""
        raise MissingTensorsError(
            f"the tensor policy found no lookup tensors in {folder} ({source}){where}: expected "
            f"{' and/or '.join(TENSOR_FILES.values())} with their .json sidecars. Train and "
            "export them with `lit train --export DIR`, or use the fixed or fit policy"
        )
    interval = 0
    if "psi_K" in tensors:
        interval = trained_decision_interval(folder / TENSOR_FILES["psi_K"])
    if interpolation is None:
        interpolation = sidecar_interpolation(folder, list(tensors))
    return lit_core.TensorPolicy(
        tensors.get("B"), tensors.get("psi_K"), INTERPOLATIONS[interpolation], interval
    )


def sidecar_interpolation(folder: Path, outputs: Sequence[str]) -> str:
    """The lookup mode that the sidecars of ``folder``'s tensors of ``outputs`` (B, psi_K) name:
    the tensor policy uses one mode for both.

    Raises:
        TensorFileError: a sidecar is defective, or the sidecars name different modes.
    """
    from lit_planner import tensor_files

    named = {
        output: tensor_files.read_sidecar(folder / TENSOR_FILES[output]).interpolation
        for output in outputs
    }
    if len(set(named.values())) > 1:
        raise TensorFileError(
            f"{folder}: the sidecars name different lookup modes "
            f"({', '.join(f'{output}: {mode}' for output, mode in named.items())}); "
            "choose one (interpolation=, --interpolation)"
        )
    return next(iter(named.values()))


def policy_params(policy: lit_core.ParameterPolicy | None) -> dict[str, str]:
    """The planner parameters that :func:`plan` sets for ``policy`` when the caller gives none:
    ``decision_interval`` for a ``tensor`` policy whose psi_K tensor names its training
    interval, else nothing."""
    if isinstance(policy, lit_core.TensorPolicy) and policy.decision_interval:
        return {"decision_interval": str(policy.decision_interval)}
    return {}


def trained_decision_interval(path: Path) -> int:
    """The expansions per psi_K decision that the psi_K tensor at ``path`` was trained with: its
    sidecar's ``provenance.decision_interval`` (``lit train`` writes it), 0 where not given.

    Raises:
        TensorFileError: the sidecar is defective, or names an interval that is not a whole
            number from 1 to :data:`MAX_DECISION_INTERVAL`.
    """
    from lit_planner import tensor_files

    sidecar = tensor_files.read_sidecar(path)
    value = sidecar.provenance.get("decision_interval")
    if value is None:
        return 0
    if (
        isinstance(value, bool)
        or not isinstance(value, int)
        or not 1 <= value <= MAX_DECISION_INTERVAL
    ):
        raise TensorFileError(
            f"{tensor_files.sidecar_path(path)}: $.provenance.decision_interval must be a whole "
            f"number from 1 to {MAX_DECISION_INTERVAL}, got {value!r}"
        )
    return value


class TensorPolicyCache:
    """The ``tensor`` policy of a folder, made again only when its files change.

    For a process that plans many queries with the same tensors (the planner node): reading and
    checking two 4 MB tensors takes about 40 ms and, just before a timed search, evicts the
    planner's data from the caches. A folder's tensor files and sidecars are compared by device,
    inode, size and modification and change times (``os.stat``) at every :meth:`get`; a tensor
    rewritten in place (as an export writes it), replaced, added or removed is read and checked
    again, and a defective one raises as :func:`make_policy` does, dropping the cached policy.
    Thread-safe.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._policies: dict[tuple[str, str | None], tuple[tuple[object, ...], Any]] = {}

    def get(
        self, tensors_dir: Path | str | None = None, interpolation: str | None = None
    ) -> lit_core.ParameterPolicy:
        """:func:`make_policy` ``("tensor", tensors_dir, interpolation)``, from the cache while
        the folder's tensor files and sidecars are unchanged.

        Raises:
            As :func:`make_policy`.
        """
        folder = default_tensors_dir() if tensors_dir is None else Path(tensors_dir)
        key = (os.path.abspath(folder), interpolation)
        signature = tensor_files_signature(folder)
        with self._lock:
            cached = self._policies.get(key)
            if cached is not None and cached[0] == signature:
                return cached[1]
            self._policies.pop(key, None)
        for _ in range(TENSOR_READS):
            policy = make_policy("tensor", folder, interpolation)
            # An export that replaced the B tensor and then the psi_K one while they were read
            # gave a policy of one export's B and the other's psi_K: read again.
            after = tensor_files_signature(folder)
            if after == signature:
                break
            signature = after
        else:
            return policy  # changed during every read: not kept for files it may not match
        with self._lock:
            self._policies[key] = (signature, policy)
        return policy


def tensor_files_signature(folder: Path) -> tuple[object, ...]:
    """(device, inode, size, modification and change times in ns) of each tensor file and
    sidecar in ``folder``, None for a missing one: what :class:`TensorPolicyCache` compares (the
    change time is the one a copy that keeps the source's modification time cannot set)."""
    return tuple(
        version
        for file_name in TENSOR_FILES.values()
        for version in _file_versions(folder / file_name)
    )


def _file_versions(path: Path) -> tuple[tuple[int, ...] | None, ...]:
    """(device, inode, size, modification and change times in ns) of the tensor ``path`` and of
    its sidecar (``tensor_files.sidecar_path``), None for a missing one: os.replace gives a file
    another inode, a write in place another size or time."""
    versions: list[tuple[int, ...] | None] = []
    for file in (path, path.with_suffix(".json")):
        try:
            stat = file.stat()
        except OSError:
            versions.append(None)
            continue
        versions.append(
            (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns, stat.st_ctime_ns)
        )
    return tuple(versions)


def _declared_output(path: Path) -> str | None:
    """The output (``B`` or ``psi_K``) that the sidecar of ``path`` names, read without its
    schema; None when it names none of them or does not read (the full check says why)."""
    from lit_planner import tensor_files  # pulls in the JSON-Schema validator

    try:
        document = json.loads(tensor_files.read_sidecar_bytes(path.with_suffix(".json")))
        name = document["output"]["name"]
    except (TensorFileError, ValueError, KeyError, TypeError, RecursionError):
        return None
    return name if name in TENSOR_FILES else None


TENSOR_READS = 3
"""Reads of a tensor and its sidecar that an export replacing them may cut into before
:func:`load_tensor` gives up."""


def load_tensor(path: str | Path, output: str) -> lit_core.LookupTensor:
    """Load the lookup tensor of ``output`` (``B`` or ``psi_K``) with the C++ reader.

    The sidecar gives the shape and value range that the C++ reader checks the file against
    (magic, version, dtype, order, shape, size, finiteness, range); the Python reader then checks
    the data against the sidecar's SHA-256, so a tensor replaced without its sidecar is caught.
    An export replaces the two files one after the other: a read that either file was replaced
    during (another inode, size or time afterwards) is done again, so the tensor returned is
    the one whose bytes were hashed and a read cut by an export is not a false "SHA-256
    differs". A read that fails while an export holds the folder (a read wholly between its
    two renames saw the new sidecar beside the old tensor) waits for the export to end, for
    ``tensor_files.EXPORT_WAIT`` seconds at most, and is done again.

    Raises:
        TensorFileError: the file, its sidecar, or the pair is defective; names the problem.
    """
    path = Path(path)  # the planner node names its fallback tensors with text
    if path.suffix != ".npy":  # no sidecar to watch: the read names the problem
        return _load_tensor_once(path, output)
    for _ in range(TENSOR_READS):
        before = _file_versions(path)
        try:
            tensor = _load_tensor_once(path, output)
        except TensorFileError:
            if _file_versions(path) == before and not _export_ended(path.parent):
                raise
            continue
        if _file_versions(path) == before:
            return tensor
    raise TensorFileError(
        f"{path}: it or its sidecar was replaced during each of {TENSOR_READS} reads; "
        "is an export writing this folder over and over?"
    )


def _export_ended(folder: Path) -> bool:
    """Whether an export was writing ``folder`` and has ended (``tensor_files.wait_for_exports``)."""
    from lit_planner import tensor_files  # pulls in the JSON-Schema validator

    return tensor_files.wait_for_exports(folder)


def _load_tensor_once(path: Path, output: str) -> lit_core.LookupTensor:
    """One read of :func:`load_tensor`."""
    # Imported here: it pulls in the JSON-Schema validator, which other policies never need.
    from lit_planner import tensor_files

    # The name first: a sidecar whose output.name says the other tensor failed the schema on
    # the rule that goes with the name ("$.output.rounding: 'none' was expected"), not this.
    declared = _declared_output(path)
    if declared is not None and declared != output:
        raise TensorFileError(
            f"{path}: its sidecar says it holds {declared!r}, but this file name is reserved "
            f"for {output!r}"
        )
    sidecar = tensor_files.read_sidecar(path)  # its schema allows B and psi_K only
    if len(sidecar.shape) != 3:
        raise TensorFileError(f"{path}: the sidecar's shape {sidecar.shape} is not 3-D")
    low, high = sidecar.value_range
    spec = tensor_files.OUTPUTS[output]
    limits = (spec.consequents[0], spec.consequents[-1])
    if low < limits[0] or high > limits[1]:
        # LIT* clamps every value to its limits: such a tensor would not be applied as trained.
        raise TensorFileError(
            f"{path}: its sidecar's value range [{low:g}, {high:g}] goes beyond LIT*'s {output} "
            f"range [{limits[0]:g}, {limits[1]:g}], to which the planner clamps every value; "
            "train with consequents inside it"
        )
    try:
        tensor = lit_core.LookupTensor.load(str(path), list(sidecar.shape), low, high)
    except lit_core.TensorError as error:
        raise TensorFileError(str(error)) from error
    tensor_files.read_tensor(path)
    return tensor


def plan(
    scenario: str | Scenario,
    planner: str = LITSTAR,
    policy: str | lit_core.ParameterPolicy | None = None,
    time: float | None = None,
    seed: int = 1,
    max_iterations: int = 0,
    max_batches: int = 0,
    tensors_dir: Path | str | None = None,
    params: Mapping[str, object] | None = None,
    listener: object | None = None,
    *,
    instance: int | None = None,
    interpolation: str | None = None,
    check_path: bool = True,
    cancel: lit_core.CancelFlag | None = None,
    features: bool = True,
) -> dict[str, Any]:
    """Plan ``scenario`` with ``planner`` and return the core's result plus scenario facts.

    Args:
        scenario: a registry name (``np8``, ``rrd8/3``) or a :class:`Scenario`.
        planner: one of :data:`PLANNER_CHOICES` (``litstar-fit`` is LIT* with the fit policy).
        policy: LIT*'s policy: a name (:data:`POLICIES`; ``external`` needs a policy object
            from :func:`make_policy`), a ``lit_core`` policy object, or None for the default
            (or the shorthand's). Must be None for the OMPL planners.
        time: time budget in seconds (LIT*: its own clock, which excludes external-policy time;
            OMPL planners: wall time). None: the scenario's budget, except that LIT* given
            ``max_iterations`` or ``max_batches`` then stops on those alone (deterministic).
        seed: LIT*'s seed. The OMPL planners draw from OMPL's global generator, which
            ``lit_core.set_global_seed`` seeds once per process.
        max_iterations, max_batches: LIT* only; 0 means no limit.
        tensors_dir, interpolation: for the ``tensor`` policy (see :func:`make_policy`).
        params: planner parameters by their ``declareParam`` names (values are stringified).
            Without ``decision_interval``, the ``tensor`` policy's psi_K tensor sets it to the
            interval it was trained with (:func:`trained_decision_interval`), if known.
        listener: object with optional ``on_solution``, ``on_decision``, ``on_batch`` methods
            (LIT* only), called with the core's event objects as they happen.
        instance: instance of a random scenario family when ``scenario`` is a name.
        check_path: run the independent re-check of the returned path now. ``lit bench`` passes
            False and checks all paths afterwards, in parallel, while no planner is timing.
        cancel: a ``lit_core.CancelFlag``; setting it from another thread ends the query early
            (the result is what the planner had by then: a node that is stopping uses it).
        features: False spares a policy that needs no features (fixed, fit) the path feature
            rho_local_b that only the result's decisions would show (NaN there): a scan around the
            path at every improvement, with LIT*'s clock paused (a few ms a run on np16 and rrd8).

    Returns:
        The dict of ``lit_core.solve`` (``status``, ``solved``, ``message``, ``cost``, ``t_init``,
        ``c_init``, ``checks_init`` (validity checks up to the first solution, None without
        one), ``improvements`` as (time, cost) tuples, ``path``, ``time``, ``counters``,
        ``decisions``, ``planner``, ``seed``, LIT*'s ``policy`` and ``iteration_init`` (the
        iteration that found the first solution: a rerun with that ``max_iterations`` stops
        there)) plus ``policy`` and ``iteration_init`` (None for OMPL planners or without a
        solution), ``scenario`` (name), ``instance``, ``dimension``, ``optimal_cost`` (None where
        unknown), ``time_budget`` (the limit given, None if none) and ``path_check`` (the
        independent re-check as a dict, None without a path or with ``check_path=False``).

    Raises:
        ScenarioError: unknown scenario or instance.
        PlannerError: unknown planner or policy, options that do not fit the planner, bad numbers.
        TensorFileError: see :func:`make_policy`.
        PlannerError: a planner parameter in ``params`` that the planner does not have (the
            message lists the ones it has), or a value it rejects.
    """
    problem = _scenario(scenario, instance)
    policy_name = policy.name if isinstance(policy, lit_core.ParameterPolicy) else policy
    core_planner, policy_name = resolve_planner(planner, policy_name)
    if tensors_dir is not None or interpolation is not None:
        # Ignored otherwise: a user comparing policies believed the folder or mode was used.
        if policy_name != "tensor":
            raise PlannerError(
                "tensors_dir and interpolation are for the tensor policy, not for "
                + (f"policy {policy_name!r}" if policy_name is not None else planner)
            )
        if isinstance(policy, lit_core.ParameterPolicy):
            raise PlannerError(
                "tensors_dir and interpolation are for the policy name 'tensor'; a policy object "
                "is used as it was made (pass them to make_policy)"
            )
    if listener is not None and core_planner != LITSTAR:
        raise PlannerError(f"a listener is called by {LITSTAR} only; {planner} calls none")
    if isinstance(policy, lit_core.ParameterPolicy):
        policy_object = policy
    elif policy_name is None:
        policy_object = None
    elif policy_name == "external":
        raise PlannerError(
            "the external policy needs a callable: pass make_policy('external', callback=...)"
        )
    else:
        policy_object = make_policy(policy_name, tensors_dir, interpolation)

    for name, argument in _ARGUMENT_PARAMS.items():
        if params and name in params:
            # The parameter would win over the argument, and the result report the argument.
            raise PlannerError(
                f"params {name!r} is given as an argument of plan: use {argument}= instead"
            )
    # A psi_K tensor is used as it was trained: one decision every that many expansions.
    params = {**policy_params(policy_object), **(params or {})}
    check_count(max_iterations, "max_iterations")
    check_count(max_batches, "max_batches")
    check_seed(seed)
    stops_on_count = bool(max_iterations or max_batches)
    check_stops_on_count(core_planner, stops_on_count)
    if time is None:
        time = 0.0 if stops_on_count else problem.time_budget
    elif not (_is_real(time) and math.isfinite(time) and time > 0):
        raise PlannerError(f"time must be a finite positive number of seconds, got {time!r}")
    elif time > MAX_TIME:
        raise PlannerError(f"time must be at most {MAX_TIME:g} s, got {time:g}")

    try:
        result: dict[str, Any] = lit_core.solve(
            query_for(problem),
            core_planner,
            time=time,
            policy=policy_object,
            seed=seed,
            max_iterations=max_iterations,
            max_batches=max_batches,
            params={key: _param_text(value) for key, value in params.items()},
            listener=listener,
            cancel=cancel,
            features=features,
        )
    except ValueError as error:
        # The core's checks of its arguments (an unknown parameter, a value it rejects, ...)
        # become PlannerErrors; any other ValueError (a listener's own) passes unchanged.
        if type(error) is ValueError and _CORE_ARGUMENT_ERROR.match(str(error)):
            raise PlannerError(str(error)) from None
        raise
    result.setdefault("policy", None)
    result.setdefault("iteration_init", None)
    result.update(
        scenario=problem.name,
        instance=problem.instance,
        dimension=problem.dim,
        optimal_cost=problem.optimal_cost,
        time_budget=time if time > 0 else None,
        path_check=(
            dataclasses.asdict(scenarios.check_path(problem, result["path"]))
            if result["path"] and check_path
            else None
        ),
    )
    return result


def _is_whole(value: object) -> bool:
    """An integer (numpy's too), not a bool: the core's arguments would refuse anything else."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: object) -> bool:
    """A real number (numpy's too), not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def check_seed(seed: int) -> None:
    """Raise :class:`PlannerError` unless ``seed`` is a whole number that fits the core's unsigned
    32-bit seeds."""
    if not _is_whole(seed) or not 0 <= seed <= MAX_SEED:
        raise PlannerError(f"seed must be a whole number between 0 and {MAX_SEED}, got {seed!r}")


def ompl_global_seed(seed: int) -> int:
    """The seed given to OMPL's global generator for ``seed``: itself, or 1 for 0, which OMPL
    cannot take (it uses 1 instead, with a warning that the baselines' log level hides)."""
    return max(seed, 1)


def quiet_ompl(planner: str) -> None:
    """Set OMPL's console to warnings for LIT* and to errors for the OMPL planners.

    OMPL 1.5.2's BIT* and ABIT* warn about their own names at construction; that says nothing
    about the run, so the baselines only report errors.
    """
    is_litstar = planner == LITSTAR or planner in SHORTHANDS
    lit_core.set_log_level("warn" if is_litstar else "error")


def json_safe(value: Any) -> Any:
    """``value`` as JSON-able data: tuples become lists and non-finite floats become None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(key): json_safe(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(item) for item in value]
    if isinstance(value, Path):
        return str(value)
    return value


def _scenario(scenario: str | Scenario, instance: int | None) -> Scenario:
    if isinstance(scenario, Scenario):
        if instance is not None and instance != scenario.instance:
            raise PlannerError(
                f"instance {instance} given with scenario {scenario.key!r} of instance "
                f"{scenario.instance}"
            )
        return scenario
    return scenarios.get(scenario, instance)


def _param_text(value: object) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    return str(value)


def plan_interruptibly(*args: Any, **kwargs: Any) -> dict[str, Any]:
    """:func:`plan` on a thread of its own: the main thread stays in Python, so Ctrl-C (or a
    signal handler that raises ``KeyboardInterrupt``) stops the query within an iteration
    through a ``lit_core.CancelFlag`` (inside the core, Python's handler could only run once the
    whole budget was spent), and is then raised. The commands that plan (lit plan, lit bench,
    lit crosscheck) plan this way; ``cancel`` may not be given."""
    cancel = lit_core.CancelFlag()
    outcome: dict[str, Any] = {}
    done = threading.Event()  # not Thread.join: one interrupted by Ctrl-C may return early after

    def work() -> None:
        try:
            outcome["result"] = plan(*args, cancel=cancel, **kwargs)
        except BaseException as error:  # noqa: BLE001 -- raised again on the main thread
            outcome["error"] = error
        finally:
            done.set()

    threading.Thread(target=work, name="plan", daemon=True).start()
    try:
        done.wait()  # a lock wait that signal handlers interrupt (no polling while the query runs)
    except KeyboardInterrupt:
        cancel.set()
        while True:  # the core stops within an iteration; exiting under it would abort
            try:
                done.wait()
                break
            except KeyboardInterrupt:  # a second Ctrl-C: still wait for that iteration
                continue
        raise
    if "error" in outcome:
        raise outcome["error"]
    return outcome["result"]

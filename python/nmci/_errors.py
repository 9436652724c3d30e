"""nmci's exceptions: one class per kind of failure, each also a ValueError (bad input) or a
RuntimeError (a computation that could not deliver), carrying the Rust message (the same text the
CLI prints)."""


from typing import Optional


class NmciError(Exception):
    """Base class of every error nmci raises.

    ``field`` names the request field at fault (``"pa"``, ``"samples"``, ``"estimates[1].p"``:
    the JSON contract's names, as the page's ``Error.field``), or is ``None`` when no single
    field is.
    """

    def __init__(self, message: str, field: Optional[str] = None) -> None:
        super().__init__(message)
        self.field = field


class RequestError(NmciError, ValueError):
    """A request field missing, unknown, of the wrong type or out of range."""


class InputError(NmciError, ValueError):
    """A matrix, vector or pattern that cannot be fused (not square, not symmetric, not positive
    definite, sizes that differ, ...)."""


class SampleError(NmciError, RuntimeError):
    """The sampler of admissible cross-covariances could not deliver (e.g. the rejection sampler
    used up its trial budget)."""


class SolveError(NmciError, RuntimeError):
    """A semidefinite program did not produce a usable bound."""


class TimeLimitError(SolveError):
    """A solve stopped at its ``time_limit``."""


class StudyError(NmciError, ValueError):
    """An invalid study configuration (unknown key, value out of range, a network that is not
    connected, ...)."""


class SimulationError(NmciError, RuntimeError):
    """A study that failed while running (a filter diverged, a fusion failed)."""


class MergeError(NmciError, ValueError):
    """Shards that do not make one study (gaps, overlaps, another study's shard, not a shard)."""


class OutputError(NmciError, OSError):
    """A study's files could not be written."""


class InternalError(NmciError, RuntimeError):
    """A bug in nmci (a Rust panic, caught before it could crash the interpreter)."""


class StructureWarning(UserWarning):
    """How a response's blocks were found, when that is worth saying: near-zero couplings
    absorbed into a proven block-diagonal bound, or a weak coupling keeping blocks merged (the
    response's ``structure["note"]``; the CLI prints it on stderr)."""


__all__ = [
    "NmciError",
    "RequestError",
    "InputError",
    "SampleError",
    "SolveError",
    "TimeLimitError",
    "StudyError",
    "SimulationError",
    "MergeError",
    "OutputError",
    "InternalError",
    "StructureWarning",
]

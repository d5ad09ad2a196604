"""clsas's own exception types (ground floor: imports nothing of clsas).

Bad arguments raise the built-in ``ValueError`` / ``TypeError`` naming the parameter, the value
and what is allowed; the types here are for what is not an argument's fault.
"""


class ClsasError(Exception):
    """Base of clsas's own exceptions."""


class EstimationError(ClsasError, RuntimeError):
    """An estimator found nothing it can stand behind (e.g. no peak stands out of the background);
    the message names the receiver or stage and the measured figure against its threshold."""


class DataFileError(ClsasError, ValueError):
    """A file that :func:`clsas.load` cannot read as clsas data: the message names the file and
    what is wrong with it (missing item, wrong shape or type, declared size over the budget)."""


class MemoryBudgetError(ClsasError, ValueError):
    """A request (its sizes follow from the arguments named in the message) would allocate more
    than :func:`clsas.memory_budget` allows; refused before anything is allocated. Raise the budget
    with :func:`clsas.use_memory_budget` or the ``CLSAS_MEMORY_BUDGET`` environment variable."""


class ScenarioFileError(ClsasError, ValueError):
    """A TOML scenario that :func:`clsas.load_scenario` cannot build: the message names the
    file, the key path (``[waveform].bandwidth``, ``[[targets]][2].velocity``), what is wrong
    and the line."""

"""Errors raised for bad models and bad input. Each names where the problem is."""

__all__ = ["ModelError", "ModelErrors", "DomainError", "ConformanceError", "UsageError", "Terminated"]


class ModelError(ValueError):
    """A model is malformed. ``element`` is a path such as ``fsms.arm.edges[3].guard``."""

    def __init__(self, element: str, problem: str, file: "str | None" = None):
        self.element, self.problem, self.file = element, problem, file
        super().__init__(self._text())

    def _text(self) -> str:
        where = f"{self.file}: " if self.file else ""
        return f"{where}{self.element}: {self.problem}" if self.element else f"{where}{self.problem}"

    def at(self, prefix: str = "", file: "str | None" = None) -> "ModelError":
        """The same error with ``prefix`` put before its element path and ``file`` set."""
        element = f"{prefix}.{self.element}" if prefix and self.element else (prefix or self.element)
        return ModelError(element, self.problem, file or self.file)


class ModelErrors(ModelError):
    """Several problems of one model found in one pass (``errors``: each a ``ModelError``,
    in the order found). It reads as the first one (``element``, ``problem``, ``file``);
    its text is one line listing them all (the command line prints one line each)."""

    def __init__(self, errors: "list[ModelError]", stopped: bool = False) -> None:
        self.errors = list(errors)
        self.stopped = stopped  # the search stopped at a cap: there may be more
        first = self.errors[0]
        super().__init__(first.element, first.problem, first.file)

    def _text(self) -> str:
        more = " (the first ones: more may follow)" if getattr(self, "stopped", False) else ""
        return f"{len(self.errors)} problems{more}: " + "; ".join(e._text() for e in self.errors)

    def at(self, prefix: str = "", file: "str | None" = None) -> "ModelErrors":
        return ModelErrors([e.at(prefix, file) for e in self.errors], self.stopped)


def collected(errors: "list[ModelError]") -> "ModelError | None":
    """One error for a list of them: None, the error itself, or a ``ModelErrors``."""
    if not errors:
        return None
    return errors[0] if len(errors) == 1 else ModelErrors(errors)


class DomainError(RuntimeError):
    """An effect wrote a value outside its variable's domain while the model ran."""

    def __init__(self, var: str, value: int, where: str):
        self.var, self.value, self.where = var, value, where
        super().__init__(f"{where}: writes {var} = {value}, outside its domain")


class ConformanceError(RuntimeError):
    """An implementation did something the model does not declare."""


class UsageError(Exception):
    """Bad command-line input or usage: the CLI prints it as one line and exits 2."""


class Terminated(KeyboardInterrupt):
    """Raised by the CLI's SIGTERM handler so that clean-up runs as for Ctrl-C (exit 143)."""

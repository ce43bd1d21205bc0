"""The btfsm pytest plugin (entry point ``pytest11``): model checks and cell conformance
in your own test suite.

* **Model files as tests** (opt-in): list glob patterns, relative to the rootdir, in the
  ``btfsm_models`` ini option (one per line or separated by spaces); each matching file
  becomes one test item per property
  (``model.yaml::no-dead-states``), checked once per file. A failing item's text is the
  counterexample as ``btfsm check`` prints it; a file that does not load fails one item,
  ``load``, with the one-line error. Scene files (``FILE.scene.yaml``) and BehaviorTree.CPP
  side files (``FILE.btfsm.yaml``) that match are not models and are skipped.
  ``btfsm_properties`` (default: all; one per line or separated by spaces),
  ``btfsm_goal_level`` (open or tree) and ``btfsm_semantics`` tune the check.
* **The ``btfsm`` fixture**: ``btfsm.check(model, properties=None, **options)`` and
  ``btfsm.conform(model, scenarios=10, seed=0, **options)`` (``btfsm.testing``).

Example ``pytest.ini``::

    [pytest]
    btfsm_models = robot/*.yaml
    btfsm_properties = workable-reachability no-dead-states invariants
"""
from __future__ import annotations

import fnmatch

import pytest

__all__ = ["ModelFile", "PropertyItem", "btfsm"]

MODEL_SUFFIXES = (".yaml", ".yml", ".json")
#: files beside a model that are not models: its scene (docs/cell.md) and an XML tree's side file
NOT_MODELS = (".scene", ".btfsm")


def _words(cfg, name) -> list:
    """An ini list option's entries, one per line or separated by spaces (both are written)."""
    return [w for line in cfg.getini(name) for w in line.split()]


def pytest_addoption(parser):
    parser.addini("btfsm_models", type="linelist", default=[],
                  help="btfsm: glob patterns (relative to the rootdir) of model files to check, one test per property")
    parser.addini("btfsm_properties", type="linelist", default=[],
                  help="btfsm: the properties checked in collected model files (default: all)")
    parser.addini("btfsm_goal_level", default="open", help="btfsm: goal-reachability level, open or tree")
    parser.addini("btfsm_semantics", default="", help="btfsm: check collected models under this profile")


def pytest_collect_file(file_path, parent):
    patterns = _words(parent.config, "btfsm_models")
    if not patterns or file_path.suffix.lower() not in MODEL_SUFFIXES:
        return None
    if any(file_path.stem.lower().endswith(x) for x in NOT_MODELS):
        return None
    try:
        rel = file_path.relative_to(parent.config.rootpath).as_posix()
    except ValueError:
        rel = file_path.as_posix()
    if any(fnmatch.fnmatch(rel, pat) for pat in patterns):
        return ModelFile.from_parent(parent, path=file_path)
    return None


class PropertyFailed(Exception):
    """A property is violated or undecided; the message is the report."""


class ModelFile(pytest.File):
    """One model file: a test item per property, sharing one check."""

    def collect(self):
        from btfsm.errors import ModelError
        from btfsm.verify.properties import PROPERTIES

        cfg = self.config
        self.properties = _words(cfg, "btfsm_properties") or list(PROPERTIES)
        unknown = [p for p in self.properties if p not in PROPERTIES]
        if unknown:
            raise pytest.UsageError(f"btfsm_properties: unknown {', '.join(unknown)} (known: {', '.join(PROPERTIES)})")
        self._report = None
        try:
            from btfsm.files import load_model

            self.model = load_model(str(self.path), semantics=cfg.getini("btfsm_semantics") or None)
        except ModelError as exc:
            self.model, self.error = None, str(exc)
            yield PropertyItem.from_parent(self, name="load", prop=None)
            return
        for name in self.properties:
            yield PropertyItem.from_parent(self, name=name, prop=name)

    def report(self):
        if self._report is None:
            from btfsm.verify.report import check

            self._report = check(self.model, self.properties, goal_level=self.config.getini("btfsm_goal_level") or "open")
        return self._report


class PropertyItem(pytest.Item):
    """One property of one model file."""

    def __init__(self, *, prop, **kw):
        super().__init__(**kw)
        self.prop = prop

    def runtest(self):
        if self.prop is None:
            raise PropertyFailed(self.parent.error)
        from btfsm.testing import failure_text

        report = self.parent.report()
        result = report.result(self.prop)
        if result.not_applicable is not None:
            pytest.skip(f"{self.prop}: not applicable ({result.not_applicable})")
        if result.holds is not True:
            raise PropertyFailed(failure_text(type(report)(report.model, [result], report.systems,
                                                           report.seconds, report.semantics)))

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, PropertyFailed):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style)

    def reportinfo(self):
        return self.path, None, f"{self.path.name}::{self.name}"


class _Btfsm:
    """What the ``btfsm`` fixture gives a test."""

    @staticmethod
    def check(model, properties=None, **options):
        """``btfsm.testing.assert_holds``: the Report, or AssertionError with the counterexamples."""
        from btfsm.testing import assert_holds

        return assert_holds(model, properties, **options)

    @staticmethod
    def conform(model, **options):
        """``btfsm.testing.assert_conforms``: the Conformance, or AssertionError with the first mismatch."""
        from btfsm.testing import assert_conforms

        return assert_conforms(model, **options)

    @staticmethod
    def load(model, semantics=None):
        """The Model of a file, ``file.py:function`` or built-in name."""
        from btfsm.testing import as_model

        return as_model(model, semantics)


@pytest.fixture
def btfsm():
    """Model checks and cell conformance as assertions (``btfsm.testing``)."""
    return _Btfsm()

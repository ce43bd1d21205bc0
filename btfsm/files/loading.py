"""Loading: files, built-in models, models written in Python, BehaviorTree.CPP XML."""
from __future__ import annotations

import dataclasses
import importlib
import os
import re
from pathlib import Path
from typing import Any, cast

from ..errors import ModelError, ModelErrors
from ..model import Model
from ..profiles import PROFILES, TICKS

from .reading import model_from_data
from .text import FORMATS, err, load_data, read_model_bytes


def builtin_models() -> dict:
    """The registry of built-in models (``btfsm.models.registry.BUILTIN``); empty when absent."""
    try:
        from btfsm.models.registry import BUILTIN
    except ImportError as exc:
        if getattr(exc, "name", None) in ("btfsm.models", "btfsm.models.registry"):
            return {}
        raise
    return dict(BUILTIN)


def load_model(ref, *, file_name: "str | None" = None, semantics: "str | None" = None,
               tick: "str | None" = None, **xml) -> Model:
    """A Model from a file (.yaml/.yml/.json) or a built-in name (``builtin_models()``).

    ``semantics`` (a ``btfsm.profiles`` name) overrides the profile the model names,
    ``tick`` (``once``, ``exactly-once``) the way a BehaviorTree.CPP main loop ticks it.

    Built-in entries are ``module:function`` (a shipped function returning a Model) or a
    file path relative to the ``models`` package; user input never names a module.

    ``xml``: ``node_library``, ``nodes``, ``main_tree`` for a BehaviorTree.CPP XML file
    (``load_xml_model``); an error for any other model."""
    xml = {k: v for k, v in xml.items() if v}
    model = _load_model(ref, file_name, xml)
    semantics = model.semantics if semantics is None else semantics
    tick = model.tick if tick is None else tick
    if semantics == model.semantics and tick == model.tick:
        return model
    source = getattr(model, "source")  # set by _with_source
    if semantics not in PROFILES:
        raise err("semantics", f"unknown semantics {semantics!r} (one of: {', '.join(PROFILES)})", source)
    if tick not in TICKS:
        raise err("tick", f"unknown tick {tick!r} (one of: {', '.join(TICKS)})", source)
    try:
        new = dataclasses.replace(model, semantics=semantics, tick=tick)
        object.__setattr__(new, "warnings", new.warnings + tuple(w for w in model.warnings if w not in new.warnings))
        return with_source(new, source)
    except ModelError as exc:
        raise (exc if exc.file else exc.at(file=source)) from None


def load_cli_model(args) -> Model:
    """The model a command's arguments name: ``args.model``, under ``args.semantics`` and
    ``args.tick`` when given (and ``--node-library``, ``--nodes``, ``--main-tree`` for an XML tree);
    the flags of ``btfsm.cliargs.model``."""
    return load_model(args.model, semantics=args.semantics, tick=args.tick, node_library=args.node_library,
                      nodes=args.nodes or (), main_tree=args.main_tree)


def _load_model(ref, file_name, xml=None) -> Model:
    text = os.fspath(ref) if isinstance(ref, os.PathLike) else ref
    if not isinstance(text, str) or not text:
        raise err("", f"expected a model file or a built-in model name, got {text!r}")
    python = python_model_ref(text)
    if python is not None:
        return with_source(load_python_model(*python, shown=file_name or text), file_name or text)
    suffix = Path(text).suffix.lower()
    if suffix == ".py" and not os.path.isdir(text):
        raise err("", "a model written in Python is named FILE.py:FUNCTION (the function returns a Model)", file_name or text)
    registry = {} if suffix in FORMATS or os.sep in text or "/" in text else builtin_models()
    if text in registry:
        return with_source(_load_builtin(text, registry[text], file_name), file_name or text)
    if suffix == ".xml":
        return with_source(load_xml_model(text, file_name=file_name, **(xml or {})), file_name or text)
    if xml:
        opts = ", ".join("--" + k.replace("_", "-") for k in xml)
        raise err("", f"{opts}: only for a BehaviorTree.CPP XML tree (.xml); {text} is not one", file_name or text)
    if suffix in FORMATS or os.path.exists(text):
        if os.path.isdir(text):
            raise err("", "is a folder, not a model file", file_name or text)
        duplicates: list = []
        data = load_data(text, file_name=file_name, duplicates=duplicates)
        return with_source(model_from_data(data, file_name or text, earlier=duplicates), file_name or text)
    names = ", ".join(sorted(builtin_models())) or "none installed"
    raise err("", f"no such file or built-in model '{text}' (model files end in .yaml, .yml, .json or .xml; built-in models: {names})")


def load_xml_model(path, *, leaves=None, file_name: "str | None" = None, node_library: "str | None" = None,
                   nodes=(), main_tree: "str | None" = None) -> Model:
    """A Model from a BehaviorTree.CPP XML v4 file and its side file (``leaves``, or
    ``STEM.btfsm.yaml`` beside the XML when found): ``btfsm.interop.btcpp_import``.

    ``node_library`` names a node library (``btfsm.interop.libraries``; else the side
    file's ``node_library``), ``nodes`` are Groot2 node model files (``TreeNodesModel``;
    the side file's ``node_models`` add to them, relative to the side file), ``main_tree``
    the BehaviorTree to check. ``<include path=...>`` is read relative to the including
    file, within the folder of ``path``."""
    from ..interop.btcpp_import import parse_xml, side_file_for, xml_to_data
    from ..interop.groot import models_of_document
    from ..interop.libraries import load_library

    shown = file_name or os.fspath(path)
    xml = read_model_bytes(path, shown)
    side_path = leaves if leaves is not None else side_file_for(path)
    side_name = None if side_path is None else os.fspath(side_path)
    side = {} if side_path is None else load_data(side_path)
    lib_name = node_library if node_library is not None else (side.get("node_library") if isinstance(side, dict) else None)
    if lib_name is not None and not isinstance(lib_name, str):
        raise err("node_library", "expected the name of a node library", side_name)
    try:
        library = load_library(lib_name) if lib_name is not None else None
    except ModelError as exc:
        raise (exc if node_library is not None else exc.at(file=side_name)) from None
    files = [(os.fspath(f), os.fspath(f)) for f in nodes]
    side_models = side.get("node_models") if isinstance(side, dict) else None
    if side_models is not None:
        if isinstance(side_models, str):
            side_models = [side_models]
        if not isinstance(side_models, list) or not all(isinstance(x, str) for x in side_models):
            raise err("node_models", "expected a node model file (or a list of them), relative to the side file", side_name)
        base = Path(cast(str, side_name)).parent
        files += [(os.fspath(base / x), x) for x in side_models]
    models: dict = {}
    for f, _text in files:
        models.update({k: v for k, v in models_of_document(parse_xml(read_model_bytes(f, f), f), f).items()
                       if k not in models})
    top = Path(path).resolve().parent

    def include(text, including):
        here = Path(including).parent if including != shown else Path(path).parent
        target = (here / text)
        real = target.resolve()
        if top not in real.parents:
            raise err("", f"<include path=\"{text}\"> leads outside the folder of {shown} ({top}): refused")
        name = os.path.normpath(target)  # one name per file, so that a cycle of includes is seen
        return parse_xml(read_model_bytes(real, name), name), name

    result = xml_to_data(xml, shown, side, side_name, library=library, models=models, main_tree=main_tree,
                         include=include)
    try:
        model = model_from_data(result.data, side_name or shown)
    except ModelErrors as exc:
        raise ModelErrors([result.locate(e, shown) for e in exc.errors], exc.stopped) from None
    except ModelError as exc:
        raise result.locate(exc, shown) from None
    object.__setattr__(model, "warnings", model.warnings + tuple(result.warnings))
    return model


_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*\Z")


def python_model_ref(text: str) -> "tuple | None":
    """``(file or module, function)`` when ``text`` names a model written in Python:
    ``path/to/file.py:function`` or ``package.module:function``; None otherwise (an existing
    file of that exact name stays a file).

    >>> python_model_ref("models/examples/two_area.py:two_area")
    ('models/examples/two_area.py', 'two_area')
    >>> python_model_ref("btfsm.models.pickplace:pickplace")
    ('btfsm.models.pickplace', 'pickplace')
    >>> python_model_ref("model.yaml") is None, python_model_ref("a:b:c") is None
    (True, True)
    """
    where, colon, func = text.rpartition(":")
    if not colon or not _IDENT.match(func) or os.path.exists(text):
        return None
    if where.lower().endswith(".py") or _MODULE.match(where):
        return where, func
    return None


#: modules of btfsm's command line: calling their functions as a model would run btfsm again
_COMMAND_LINES = frozenset({"btfsm.cli", "btfsm.__main__", "btfsm.sim.cli", "btfsm.pytest_plugin"})


def load_python_model(where: str, func: str, *, shown: "str | None" = None) -> Model:
    """Call ``func`` of the Python file or module ``where`` (the user's explicit choice to
    run their code) and return the Model it builds; anything else is a one-line ModelError."""
    import importlib.util
    import sys

    shown = shown or f"{where}:{func}"
    try:
        if where.lower().endswith(".py"):
            if not os.path.isfile(where):
                raise err("", f"no such Python file '{where}'", shown)
            name = "_btfsm_user_model_" + re.sub(r"\W", "_", os.path.abspath(where))
            spec = importlib.util.spec_from_file_location(name, where)
            if spec is None or spec.loader is None:
                raise err("", f"cannot load '{where}' as a Python module", shown)
            module = importlib.util.module_from_spec(spec)
            folder = os.path.dirname(os.path.abspath(where))
            sys.path.insert(0, folder)  # its sibling modules import as they would when run as a script
            try:
                spec.loader.exec_module(module)
            finally:
                if sys.path and sys.path[0] == folder:
                    del sys.path[0]
        else:
            module = importlib.import_module(where)
    except ModelError:
        raise
    except ModuleNotFoundError as exc:
        raise err("", f"cannot import '{where}': no module named '{exc.name}'", shown) from None
    except SyntaxError as exc:
        raise err("", f"{exc.filename or where}: line {exc.lineno}: syntax error: {exc.msg}", shown) from None
    except MemoryError:
        raise
    except (Exception, SystemExit) as exc:  # the user's module raised while it was imported
        raise err("", f"importing '{where}' raised {type(exc).__name__}: {exc}", shown) from None
    fn = getattr(module, func, None)
    if not callable(fn):
        raise err("", f"'{where}' has no function '{func}'", shown)
    if getattr(fn, "__module__", None) in _COMMAND_LINES:
        raise err("", f"{func}() is btfsm's own command line, not a function that returns a Model", shown)
    try:
        model = fn()
    except ModelError as exc:
        raise (exc if exc.file else exc.at(file=shown)) from None
    except MemoryError:
        raise
    except (Exception, SystemExit) as exc:
        raise err("", f"{func}() raised {type(exc).__name__}: {exc}", shown) from None
    if not isinstance(model, Model):
        raise err("", f"{func}() returned {type(model).__name__}, not a btfsm Model", shown)
    return model


def with_source(model: Model, shown: str) -> Model:
    """Record where the model came from (``model.source``: the file or built-in name that
    messages show; not part of the model's value), so that later errors can name it."""
    object.__setattr__(model, "source", shown)
    return model


def _load_builtin(name, entry, file_name):
    shown = file_name or name
    if not isinstance(entry, str):
        raise err("", f"registry entry for '{name}' is not a string", shown)
    if Path(entry).suffix.lower() in FORMATS:
        import btfsm.models as shipped  # the package the registry lives in

        path = Path(shipped.__file__).parent / entry
        duplicates: list = []
        data = load_data(path, file_name=shown, duplicates=duplicates)
        return model_from_data(data, shown, earlier=duplicates)
    module, _, func = entry.partition(":")
    if not module or not func:
        raise err("", f"registry entry '{entry}' for '{name}' is neither module:function nor a model file", shown)
    try:
        model = getattr(importlib.import_module(module), func)()
    except ModelError as exc:
        raise exc.at("", shown) from None
    if not isinstance(model, Model):
        raise err("", f"built-in '{name}' ({entry}) returned {type(model).__name__}, not a Model", shown)
    return model

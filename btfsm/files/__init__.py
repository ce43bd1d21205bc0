"""Model files: YAML and JSON in and out, templates, and ``btfsm validate``.

One data model for both formats (docs/model-files.md is the reference; the JSON Schema is
``btfsm/schema/model.schema.json``). Loading never executes code: YAML is composed with a
safe loader (YAML 1.2 core scalars: ``yes``, ``no``, ``on``, ``off`` stay strings) and turned into
plain dicts, lists and scalars by this module; templates are text substitution of
declared ``${PARAM}`` placeholders; expressions are parsed by ``btfsm.expr.parse``. Every
problem is a ``ModelError`` naming the file, the element path in the file (such as
``fsms.arm.edges[3].guard``) and, for YAML, the line; a file's independent problems are
raised together, as one ``ModelErrors`` (``reading``: up to ``MAX_ERRORS``).

The package has one module per job, each importing only the ones before it:
``text`` (reading text with limits, the one-line errors), ``templates``, ``repair``
(the problems of a Model's checks repaired to find the next), ``reading`` (data to
Model), ``loading`` (files, built-in models, Python modules, XML), ``writing``
(Model to data) and ``validate`` (the command); ``schema`` generates the node part of the
JSON Schema from the node classes (``btfsm.bt``). Every public name is imported here, so
``from btfsm.files import load_model`` is the import to use.

>>> m = loads_model('''
... name: counter
... variables: {n: {int: [0, 3]}}
... tree:
...   ReactiveFallback: root
...   children:
...     - {Condition: full, expr: n == 3}
...     - {Action: add, outcomes: [{success: {n: n + 1}}]}
... ''')
>>> m.program.initial
(0,)
>>> loads_model(dumps_model(m)) == m
True
"""
from __future__ import annotations

from .loading import builtin_models, load_cli_model, load_model, load_python_model, load_xml_model, python_model_ref
from .reading import loads_model, model_from_data
from .templates import expand_templates
from .text import FORMATS, MAX_FILE_BYTES, MAX_NODES, format_of, load_data, loads_data, read_model_bytes
from .validate import cli_validate
from .writing import dump_model, dumps_model, model_to_data

__all__ = [
    "FORMATS", "load_model", "load_cli_model", "python_model_ref", "load_python_model", "loads_model", "load_data", "loads_data", "expand_templates",
    "model_from_data", "model_to_data", "dump_model", "dumps_model", "builtin_models",
    "format_of", "cli_validate", "read_model_bytes", "MAX_FILE_BYTES", "MAX_NODES", "load_xml_model",
]

"""A Griffe extension for the API reference (docs/reference.md): the docstrings name objects with Sphinx's
roles (:func:`calibrate`, :class:`~optcal.core.calibration.Calibration`), which Markdown would print as they are; this
turns each into code that links to the object where the reference renders it, and stays plain code where it
does not (an optional mkdocs-autorefs reference, which the strict build does not count as broken).
"""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:func|class|meth|attr|data|mod|obj|exc):`(~?)([\w.]+)`")


def _identifier(obj: griffe.Object, target: str, loader: griffe.GriffeLoader) -> str:
    """The path where ``target``, as a docstring of ``obj`` names it, is defined: a relative name is looked up
    as Sphinx does, in the object's class, then module, then package; an imported name is followed to its
    definition (``optcal.core.recording.Recording`` is ``optcal.core.recording.reading.Recording``)."""
    first = target.split(".")[0]
    scope = obj if obj.is_class else obj.parent
    while scope is not None and first not in scope.members:
        scope = scope.parent
    path = target if scope is None else f"{scope.path}.{target}"
    try:
        return loader.modules_collection[path].canonical_path
    except (KeyError, ValueError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return path  # outside the loaded packages (matplotlib, ...): left as written


class SphinxRoles(griffe.Extension):
    def on_object(self, *, obj: griffe.Object, loader: griffe.GriffeLoader, **kwargs) -> None:
        if obj.is_alias or obj.docstring is None:
            return
        obj.docstring.value = ROLE.sub(
            lambda m: (f'<autoref identifier="{_identifier(obj, m[2], loader)}" optional>'
                       f"<code>{m[2].rsplit('.', 1)[-1] if m[1] else m[2]}</code></autoref>"),
            obj.docstring.value)

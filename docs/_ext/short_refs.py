"""Resolve the short cross-references stageid's docstrings use, and only those.

Docstrings name things the way their module sees them (``:class:`DataError```,
``:meth:`HankelMAP.fit```, ``:mod:`.lpm```).  A reference is linked to the one documented
object whose dotted name ends with it; a reference to a name that exists in stageid's code
but is not part of the public API (an internal module or helper) is shown as code without a
link.  Anything else - a misspelt or removed name - stays a warning, which ``-W`` makes an error.
"""

from __future__ import annotations

import importlib
import sys

from sphinx.util.nodes import make_refnode


def resolve(app, env, node, contnode):
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~")
    module = node.get("py:module") or ""
    klass = node.get("py:class") or ""
    domain = env.get_domain("py")
    match = unique_suffix_match(domain, target.lstrip("."), module)
    if match is not None:
        entry = domain.objects[match]
        return make_refnode(app.builder, node["refdoc"], entry.docname, entry.node_id, contnode, match)
    names = candidates(target, module, klass)
    home = defining_module(node["refdoc"])
    if home:  # a page of a re-exported name: its docstring speaks from the module that defines it
        names += candidates(target, home, klass)
    if any(exists(name) for name in names) or defined_somewhere(target):
        return contnode
    return None


def unique_suffix_match(domain, target: str, module: str) -> str | None:
    """The documented name ending with ``target``; the nearest to ``module`` when several do."""
    found = [name for name in domain.objects if name == target or name.endswith("." + target)]
    if len(found) > 1:
        package = ".".join(module.split(".")[:2])
        found = [name for name in found if name.startswith(package + ".")] or found
    return found[0] if len(found) == 1 else None


def candidates(target: str, module: str, klass: str) -> list[str]:
    """Dotted names ``target`` can mean from inside ``module`` (and class ``klass``)."""
    parts = module.split(".") if module else []
    if target.startswith("."):
        return [".".join(parts[: len(parts) - i] + [target.lstrip(".")]) for i in range(len(parts))]
    names = [target]
    scopes = [f"{module}.{klass}"] if klass else []
    scopes += [".".join(parts[: len(parts) - i]) for i in range(len(parts))]
    names += [f"{scope}.{target}" for scope in scopes if scope]
    return names


def defining_module(docname: str) -> str:
    """The module that defines the object an API page documents ("" for other pages)."""
    prefix = "api/generated/"
    if not docname.startswith(prefix):
        return ""
    parts = docname[len(prefix) :].split(".")
    for cut in range(len(parts) - 1, 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr, None)
        return getattr(obj, "__module__", "") or ""
    return ""


def defined_somewhere(target: str) -> bool:
    """True when a loaded stageid module defines ``target`` (a summary line quoting a helper)."""
    head, _, rest = target.partition(".")
    for name, module in list(sys.modules.items()):
        obj = getattr(module, head, None) if name.startswith("stageid.") else None
        if obj is not None and getattr(obj, "__module__", None) == name:
            return not rest or exists(f"{name}.{target}")
    return False


def exists(dotted: str) -> bool:
    """True when ``dotted`` names a module or an attribute inside stageid."""
    if not dotted.startswith("stageid"):
        return False
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        try:
            for attr in parts[cut:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


def setup(app):
    app.connect("missing-reference", resolve)
    return {"parallel_read_safe": True, "version": "1"}

"""Every error message planarcal can raise, read from its source: the ``error-catalogue``
directive of the troubleshooting page.

``raise_sites(package_dir)`` walks the package with ``ast`` and returns one ``RaiseSite`` per
place that makes one of planarcal's exceptions (``planarcal.errors``' classes and their
subclasses elsewhere in the package), with its message as a template: an f-string's variable
parts become ``{placeholders}``. It needs no Sphinx, so the tests call it directly. Sites
whose class is chosen at run time are resolved where the source says which: a parameter
(``raise exc(...)``: its default and every class the package's calls pass), a local
(``cls = ...``), or ``type(e)`` of the exception an ``except`` clause caught. The command
line's own refusals (``argparse.ArgumentError``/``ArgumentTypeError`` raised by a command:
exit status 2) are listed too. ``core_messages(rust_dir)`` adds the Rust core's homography
and lens messages, which the bindings raise as ``ArgumentError``, ``DegenerateError``,
``HomographyError`` or ``LensModelError``.

``foreign_raises(package_dir)`` lists the exceptions package code raises that are not
planarcal's (a bare ``ValueError``, ``OSError``...), for review; the page does not show them.
"""

from __future__ import annotations

import ast
import functools
import re
from collections import defaultdict
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

# The command line's refusals, raised by a command's own argument checks: status 2.
ARGPARSE_ERRORS = ("argparse.ArgumentError", "argparse.ArgumentTypeError")

# A placeholder longer than this is shown as {...}: the reader needs to see a part varies,
# not the expression that computes it.
_MAX_PLACEHOLDER = 40


@dataclass(frozen=True)
class RaiseSite:
    """One place the package makes an exception a user can meet."""

    error: str  # the class's name ("CalibrationFileError", "argparse.ArgumentError")
    message: str  # the message, variable parts as {placeholders}
    module: str  # "planarcal.calib.calibration_file"
    path: Path
    line: int
    raised: bool  # raised where it is made (False: made, then returned or kept for later)


def error_classes(package_dir: Path) -> dict[str, str]:
    """Each exception class of planarcal (errors.py's and their subclasses anywhere in the
    package) mapped to its first base's name ("Error" for the root's children, "" for the
    root itself)."""
    bases_of: dict[str, list[str]] = {}
    for _, tree in _modules(package_dir):
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                bases_of.setdefault(node.name, [_name(b) for b in node.bases])
    classes = {"Error": ""}
    grew = True
    while grew:
        grew = False
        for name, bases in bases_of.items():
            known = [b for b in bases if b in classes]
            if name not in classes and known:
                classes[name] = known[0]
                grew = True
    return classes


def raise_sites(package_dir: Path) -> list[RaiseSite]:
    """Every place in the package that makes one of planarcal's exceptions (see the module's
    docstring), in file and line order."""
    package_dir = Path(package_dir)
    classes = set(error_classes(package_dir))
    modules = list(_modules(package_dir))
    functions = _FunctionIndex(modules)
    sites: list[RaiseSite] = []
    for path, tree in modules:
        module = _module_name(package_dir, path)
        walker = _SiteWalker(classes, functions, module, path, tree)
        sites.extend(walker.sites)
    return sorted(set(sites), key=lambda s: (str(s.path), s.line, s.error, s.message))


# The detectors' reasons for refusing one candidate grid: never raised to the user, but
# quoted in BoardNotFoundError's message ("Candidates refused: ...") and its diagnostics.
REFUSAL = "_RefusedError"


def refusal_reasons(package_dir: Path) -> list[RaiseSite]:
    """Each reason a detector gives for refusing a candidate grid (``raise
    _RefusedError(...)``), as sites of the class ``REFUSAL``."""
    package_dir = Path(package_dir)
    modules = list(_modules(package_dir))
    functions = _FunctionIndex(modules)
    sites = []
    for path, tree in modules:
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Raise)
                and isinstance(node.exc, ast.Call)
                and _name(node.exc.func) == REFUSAL
                and node.exc.args
            ):
                message = functions.template(node.exc.args[0])
                module = _module_name(package_dir, path)
                sites.append(RaiseSite(REFUSAL, message, module, path, node.lineno, True))
    return sites


def foreign_raises(package_dir: Path) -> list[tuple[Path, int, str]]:
    """Each ``raise SomeError(...)`` in the package whose class is neither planarcal's nor
    argparse's: (file, line, class name)."""
    package_dir = Path(package_dir)
    classes = set(error_classes(package_dir))
    found = []
    for path, tree in _modules(package_dir):
        aliases = {
            alias.asname: alias.name
            for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom)
            for alias in node.names
            if alias.asname
        }
        for node in ast.walk(tree):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call | ast.Name):
                target = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
                name = aliases.get(_name(target), _name(target))
                if name[:1].isupper() and name not in classes and name not in ARGPARSE_ERRORS:
                    found.append((path, node.lineno, name))
    return found


def by_error(sites: Iterable[RaiseSite]) -> dict[str, list[RaiseSite]]:
    """The sites grouped by class, classes in name order (argparse's last), each group's
    messages deduplicated (the first site of each kept) in file and line order."""
    groups: dict[str, dict[str, RaiseSite]] = defaultdict(dict)
    for site in sites:
        groups[site.error].setdefault(site.message, site)
    order = sorted(groups, key=lambda name: (name in ARGPARSE_ERRORS, name))
    return {name: list(groups[name].values()) for name in order}


# The Rust core's errors: each enum's ``#[error("...")]`` texts, and the class the bindings
# raise each as (rust/planarcal-py/src/errors.rs, plane_model.rs).
_CORE_ENUMS = {
    "error.rs": "HomographyError",
    "lens.rs": "LensError",
    "fitted_mapper.rs": "UncertaintyError",
    "estimate.rs": "UnknownSolver",
}
_VARIANT = re.compile(
    r'#\[error\(\s*((?:"(?:[^"\\]|\\.)*"\s*)+)[^\]]*\)\]\s*(?:///[^\n]*\n\s*)*'
    r"(?:pub\s+)?(?:struct\s+)?(\w+)",
    re.S,
)
_RUST_STRING = re.compile(r'"((?:[^"\\]|\\.)*)"', re.S)


def core_messages(rust_dir: Path) -> list[RaiseSite]:
    """The messages of the Rust core's errors that reach Python (``rust_dir``: the repository's
    rust/ folder), each with the class the bindings raise it as."""
    src = Path(rust_dir) / "planarcal-core" / "src"
    error_rs = (src / "error.rs").read_text()
    invalid = set(re.findall(r"HomographyError::(\w+)", _body(error_rs, "fn is_invalid_argument")))
    degenerate = set(re.findall(r"HomographyError::(\w+)", _body(error_rs, "fn is_degenerate")))
    sites = []
    for file_name in _CORE_ENUMS:
        path = src / file_name
        text = path.read_text()
        for match in _VARIANT.finditer(text):
            variant = match.group(2)
            message = _rust_format(match.group(1))
            if not message:
                continue  # #[error(transparent)]: another error's own message
            if file_name == "error.rs":
                if variant == "OutOfMemory":
                    continue  # Python's MemoryError, not planarcal's
                error = (
                    "ArgumentError"
                    if variant in invalid
                    else "DegenerateError"
                    if variant in degenerate
                    else "HomographyError"
                )
            elif file_name == "lens.rs" or variant == "NoResidualDof":
                error = "LensModelError"
            else:  # an option's value: sigma, the solver's name
                error = "ArgumentError"
            line = text.count("\n", 0, match.start()) + 1
            sites.append(RaiseSite(error, message, f"planarcal-core {file_name}", path, line, True))
    return sites


# The bindings' own messages (rust/planarcal-py/src): each helper of errors.rs or class's
# new_err given a literal or a format! string, and the class it raises.
_LITERAL = r'(?:format!\(\s*)?((?:"(?:[^"\\]|\\.)*"\s*)+)'
_BINDING_CALLS = (
    (re.compile(r"\binvalid\(\s*" + _LITERAL), "ArgumentError"),
    (re.compile(r"\binvalid_arg\(\s*[^,()]+,\s*" + _LITERAL), "ArgumentError"),
    (re.compile(r"\bwrong_type\(\s*" + _LITERAL), "ArgumentTypeError"),
    (re.compile(r"\b(\w+Error)::new_err\(\s*" + _LITERAL), ""),
)
# errors.rs's messages for points without an image (or beyond the lens's valid radius).
_NO_IMAGE = re.compile(r"let message = format!\(\s*" + _LITERAL)


def binding_messages(rust_dir: Path) -> list[RaiseSite]:
    """The messages the Rust bindings make themselves (an argument's shape, an option's
    value, points without an image), each with its class."""
    sites = []
    for path in sorted((Path(rust_dir) / "planarcal-py" / "src").glob("*.rs")):
        text = path.read_text()
        found: list[tuple[int, str, str]] = []
        for pattern, error in _BINDING_CALLS:
            for match in pattern.finditer(text):
                name = error or match.group(1)
                if name.startswith("Py"):
                    continue  # Python's own (MemoryError): not planarcal's
                found.append((match.start(), name, match.groups()[-1]))
        for match in _NO_IMAGE.finditer(text):
            found.append((match.start(), "PointAtInfinityError", match.group(1)))
        for start, error, literals in found:
            line = text.count("\n", 0, start) + 1
            message = _rust_format(literals)
            sites.append(RaiseSite(error, message, f"planarcal-py {path.name}", path, line, True))
    return sorted(sites, key=lambda s: (str(s.path), s.line))


def _body(text: str, signature: str) -> str:
    """The text of the Rust function whose signature starts with ``signature``, up to its
    closing brace."""
    start = text.index(signature)
    end = text.find("\n    }\n", start)
    return text[start : end if end > 0 else len(text)]


def _rust_format(literals: str) -> str:
    """The message of a ``#[error]`` attribute's string literals: line continuations
    joined, ``{name:.1e}`` shown as ``{name}``, ``{0:?}`` as ``{0}``."""
    text = "".join(_RUST_STRING.findall(literals))
    text = re.sub(r"\\\n\s*", "", text).replace('\\"', '"')
    return re.sub(r"\{(\w*)(?::[^}]*)?\}", lambda m: "{" + (m.group(1) or "...") + "}", text)


# -- the walk ------------------------------------------------------------------------------


def _modules(package_dir: Path) -> Iterator[tuple[Path, ast.Module]]:
    for path in sorted(Path(package_dir).rglob("*.py")):
        yield path, _parse(path, path.stat().st_mtime_ns)


@functools.lru_cache(maxsize=1024)
def _parse(path: Path, mtime_ns: int) -> ast.Module:
    """The module's tree, parsed once per version of the file (the walk reads the package
    several times, and a build asks for it again)."""
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def _module_name(package_dir: Path, path: Path) -> str:
    parts = [package_dir.name, *path.relative_to(package_dir).with_suffix("").parts]
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _name(node: ast.expr) -> str:
    """A class or function as written: ``X``, ``argparse.ArgumentError``; "" for anything
    else."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        if isinstance(node.value, ast.Name) and node.value.id == "argparse":
            return f"argparse.{node.attr}"
        return node.attr
    return ""


_Function = ast.FunctionDef | ast.AsyncFunctionDef


class _FunctionIndex:
    """The package's functions by name, and every call of each, to find which classes a
    parameter such as ``exc: type[ValueError] = ArgumentError`` is given."""

    def __init__(self, modules: list[tuple[Path, ast.Module]]) -> None:
        self.defs: dict[str, list[_Function]] = defaultdict(list)
        self.calls: dict[str, list[tuple[ast.Call, _Function | None]]] = defaultdict(list)
        self._caller_of_argument: dict[int, _Function | None] = {}
        # Module-level texts by name, where one module alone defines the name.
        constants: dict[str, list[ast.expr]] = defaultdict(list)
        for _, tree in modules:
            for statement in tree.body:
                if isinstance(statement, ast.Assign) and _is_text(statement.value):
                    for target in statement.targets:
                        if isinstance(target, ast.Name) and target.id.isupper():
                            constants[target.id].append(statement.value)
        self.constants = {name: values[0] for name, values in constants.items() if len(values) == 1}
        for _, tree in modules:
            for node, function in _walk_in_functions(tree, None):
                if isinstance(node, _Function):
                    self.defs[node.name].append(node)
                elif isinstance(node, ast.Call):
                    callee = _name(node.func)
                    if callee == "partial" and node.args:  # functools.partial(f, exc=...)
                        callee = _name(node.args[0])
                        node = ast.Call(node.args[0], node.args[1:], node.keywords)
                    if callee:
                        self.calls[callee].append((node, function))
                        for argument in [*node.args, *(k.value for k in node.keywords)]:
                            self._caller_of_argument[id(argument)] = function

    def parameter_values(self, function: _Function, parameter: str) -> list[ast.expr]:
        """The default of ``function``'s ``parameter`` and what each call of a function of
        that name passes it."""
        params = [*function.args.posonlyargs, *function.args.args]
        names = [p.arg for p in params]
        values: list[ast.expr] = []
        defaults = function.args.defaults
        for param, default in zip(params[len(params) - len(defaults) :], defaults, strict=True):
            if param.arg == parameter:
                values.append(default)
        for param, kw_default in zip(
            function.args.kwonlyargs, function.args.kw_defaults, strict=True
        ):
            if param.arg == parameter and kw_default is not None:
                values.append(kw_default)
        for call, _ in self.calls.get(function.name, []):
            for keyword in call.keywords:
                if keyword.arg == parameter:
                    values.append(keyword.value)
            if parameter in names:
                position = names.index(parameter) - (1 if names[:1] in (["self"], ["cls"]) else 0)
                if 0 <= position < len(call.args):
                    values.append(call.args[position])
        return values

    def text_of(self, node: ast.expr, depth: int = 0) -> list[str]:
        """The templates of the text ``node`` names where the package says it in one place:
        a module-level constant (``MATPLOTLIB_MISSING``), or (directly in a message, not
        nested in another's text) the call of a function or method of a unique name whose
        every ``return`` is text; [] otherwise."""
        if isinstance(node, ast.Name) and node.id in self.constants and depth < 3:
            return [self.template(self.constants[node.id], depth + 1)]
        if not isinstance(node, ast.Call) or depth > 0:
            return []
        defs = self.defs.get(_name(node.func), [])
        if len(defs) != 1:
            return []
        returns = [n.value for n in ast.walk(defs[0]) if isinstance(n, ast.Return) and n.value]
        if not returns or not all(_is_text(v) for v in returns):
            return []
        return [self.template(v, depth + 1, defs[0]) for v in returns]

    def template(self, node: ast.expr, depth: int = 0, scope: _Function | None = None) -> str:
        """The text ``node`` evaluates to, its variable parts as {placeholders} (a constant
        or helper it names inlined, as ``text_of`` finds them, and within a helper
        ``scope`` its locals assigned text once)."""
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            return node.value
        if isinstance(node, ast.JoinedStr):
            return "".join(self.template(v, depth, scope) for v in node.values)
        if isinstance(node, ast.FormattedValue):  # a call inside a message stays a placeholder
            return self.template(node.value, depth + 1, scope)
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
            return self.template(node.left, depth, scope) + self.template(node.right, depth, scope)
        if isinstance(node, ast.Name) and scope is not None:
            assigned = [
                n.value
                for n in ast.walk(scope)
                if isinstance(n, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == node.id for t in n.targets)
            ]
            if len(assigned) == 1 and _is_text(assigned[0]):
                return self.template(assigned[0], depth, scope)
        if (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "format"
            and isinstance(node.func.value, ast.Name | ast.Constant)
        ):
            return self.template(node.func.value, depth, scope)  # TEXT.format(...): its fields
        inlined = self.text_of(node, depth)
        if len(inlined) == 1:
            return inlined[0]
        return _placeholder(node)

    def caller_of(self, value: ast.expr) -> _Function | None:
        """The function whose call passes ``value`` as an argument (None: not an argument,
        or passed at a module's top level)."""
        return self._caller_of_argument.get(id(value))


def _walk_in_functions(
    node: ast.AST, function: _Function | None
) -> Iterator[tuple[ast.AST, _Function | None]]:
    """Every node under ``node`` with the innermost function it lies in."""
    for child in ast.iter_child_nodes(node):
        yield child, function
        inner = child if isinstance(child, _Function) else function
        yield from _walk_in_functions(child, inner)


class _SiteWalker:
    """The raise sites of one module."""

    def __init__(
        self,
        classes: set[str],
        functions: _FunctionIndex,
        module: str,
        path: Path,
        tree: ast.Module,
    ) -> None:
        self.classes = classes
        self.functions = functions
        self.module = module
        self.path = path
        self.sites: list[RaiseSite] = []
        self._assigned: dict[int, dict[str, list[ast.expr]]] = {}
        self.aliases = self._imported_aliases(tree)
        parents: dict[ast.AST, ast.AST] = {}
        for parent in ast.walk(tree):
            for child in ast.iter_child_nodes(parent):
                parents[child] = parent
        self.parents = parents
        raised = {id(n.exc) for n in ast.walk(tree) if isinstance(n, ast.Raise) and n.exc}
        for node, function in _walk_in_functions(tree, None):
            if isinstance(node, ast.Call):
                self._call(node, function, id(node) in raised)
            elif isinstance(node, ast.Raise) and isinstance(node.exc, ast.Name):
                for error in self._classes_of(node.exc, function, set()):
                    self._add(error, "", node, raised=True)

    def _imported_aliases(self, tree: ast.Module) -> dict[str, str]:
        """Local names that are planarcal's classes imported under another name."""
        aliases = {}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for alias in node.names:
                    if alias.name in self.classes and alias.asname:
                        aliases[alias.asname] = alias.name
        return aliases

    def _call(self, call: ast.Call, function: _Function | None, raised: bool) -> None:
        errors = self._classes_of(call.func, function, set())
        if not errors:
            return
        args = call.args
        if _name(call.func) == "argparse.ArgumentError" and len(args) >= 2:
            args = args[1:]  # ArgumentError(action, message)
        first = args[0] if args else None
        if isinstance(first, ast.Starred) or (first is not None and _looks_like_errno(first, args)):
            first = args[1] if len(args) > 1 else None
        messages = self._messages(first, function) if first is not None else [""]
        for error in errors:
            for message in messages:
                self._add(error, message, call, raised)

    def _add(self, error: str, message: str, node: ast.AST, raised: bool) -> None:
        line = getattr(node, "lineno", 0)
        self.sites.append(RaiseSite(error, message, self.module, self.path, line, raised))

    def _classes_of(self, node: ast.expr, function: _Function | None, seen: set[int]) -> list[str]:
        """The planarcal classes (or argparse's errors) the expression ``node``, called,
        would make: [] where it is none of them."""
        if id(node) in seen:
            return []
        seen.add(id(node))
        name = _name(node)
        if name in ARGPARSE_ERRORS:
            return [name]
        if isinstance(node, ast.Attribute):
            return [name] if name in self.classes else []
        if isinstance(node, ast.Call) and _name(node.func) == "type" and len(node.args) == 1:
            return self._caught(node.args[0])
        if not isinstance(node, ast.Name):
            return []
        if name in self.aliases:
            return [self.aliases[name]]
        if function is None:
            return [name] if name in self.classes else []
        local = self._local_values(name, function)
        if local is None:
            return [name] if name in self.classes else []
        found: list[str] = []
        for value in local:
            # A parameter's argument is read where the call is (it may be the caller's own).
            scope = self.functions.caller_of(value) or function
            for error in self._classes_of(value, scope, seen):
                if error not in found:
                    found.append(error)
        return found

    def _local_values(self, name: str, function: _Function) -> list[ast.expr] | None:
        """What the local ``name`` of ``function`` may hold: its parameter's values (default
        and arguments), or the values assigned to it; None if it is not local."""
        params = [*function.args.posonlyargs, *function.args.args, *function.args.kwonlyargs]
        if any(p.arg == name for p in params):
            return self.functions.parameter_values(function, name)
        return self._assignments(function).get(name)

    def _assignments(self, function: _Function) -> dict[str, list[ast.expr]]:
        """Each local name assigned in ``function`` and the values it is given."""
        if id(function) not in self._assigned:
            assigned: dict[str, list[ast.expr]] = defaultdict(list)
            for node in ast.walk(function):
                if isinstance(node, ast.Assign):
                    for target in node.targets:
                        if isinstance(target, ast.Name):
                            assigned[target.id].append(node.value)
                elif (
                    isinstance(node, ast.AnnAssign)
                    and isinstance(node.target, ast.Name)
                    and node.value is not None
                ):
                    assigned[node.target.id].append(node.value)
            self._assigned[id(function)] = dict(assigned)
        return self._assigned[id(function)]

    def _caught(self, node: ast.expr) -> list[str]:
        """The planarcal classes an ``except ... as <node>`` around ``node`` catches."""
        if not isinstance(node, ast.Name):
            return []
        parent = self.parents.get(node)
        while parent is not None:
            if isinstance(parent, ast.ExceptHandler) and parent.name == node.id and parent.type:
                types = parent.type.elts if isinstance(parent.type, ast.Tuple) else [parent.type]
                return [_name(t) for t in types if _name(t) in self.classes]
            parent = self.parents.get(parent)
        return []

    def _messages(self, node: ast.expr, function: _Function | None) -> list[str]:
        """The message templates ``node`` may give: one, or one per branch where it is a
        conditional expression, an ``a or b``, or a local assigned in several places."""
        if isinstance(node, ast.IfExp):
            return self._messages(node.body, function) + self._messages(node.orelse, function)
        if isinstance(node, ast.BoolOp) and isinstance(node.op, ast.Or):
            return [m for value in node.values for m in self._messages(value, function)]
        if isinstance(node, ast.Name) and function is not None:
            assigned = self._local_values(node.id, function)
            if assigned and all(_is_text(v) for v in assigned):
                return [m for v in assigned for m in self._messages(v, function)]
        helper = self.functions.text_of(node)
        if helper:
            return helper
        return [self.functions.template(node)]


def _looks_like_errno(first: ast.expr, args: list[ast.expr]) -> bool:
    """OSError(errno, message): the message is the second argument."""
    errno_like = isinstance(first, ast.Attribute) and first.attr in ("errno",)
    errno_like |= isinstance(first, ast.Attribute) and _name(first.value) == "errno"
    return errno_like and len(args) > 1


def _is_text(node: ast.expr) -> bool:
    if isinstance(node, ast.Constant):
        return isinstance(node.value, str)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        return _is_text(node.left) or _is_text(node.right)
    return isinstance(node, ast.JoinedStr | ast.IfExp)


def _placeholder(node: ast.expr) -> str:
    """``{expression}`` for a variable part; a long call shows only what it calls."""
    if isinstance(node, ast.Call) and _name(node.func) in ("str", "repr") and node.args:
        node = node.args[0]
    text = ast.unparse(node)
    if len(text) > _MAX_PLACEHOLDER and isinstance(node, ast.Call):
        text = f"{ast.unparse(node.func)}(...)"
    return "{" + (text if len(text) <= _MAX_PLACEHOLDER else "...") + "}"


# -- the directive -----------------------------------------------------------------------


def catalogue(repository: Path) -> dict[str, list[RaiseSite]]:
    """The page's catalogue: every class's messages (the package's, then the Rust core's and
    bindings'), the command line's refusals, and the detectors' refusal reasons last."""
    package = repository / "python" / "planarcal"
    rust = repository / "rust"
    sites = raise_sites(package) + core_messages(rust) + binding_messages(rust)
    groups = by_error(sites)
    groups.update(by_error(refusal_reasons(package)))
    return groups


def _about(error: str, parents: dict[str, str], count: int) -> str:
    """The line under a class's title: what it is a kind of, and how many messages."""
    plural = "s" if count != 1 else ""
    if error == REFUSAL:
        return (
            f"Why a detector refused a candidate grid ({count} reason{plural}): not raised on "
            "their own, but quoted after 'Candidates refused:' in a BoardNotFoundError's "
            "message, and drawn by calibrate --report."
        )
    if error in ARGPARSE_ERRORS:
        return (
            f"A value the command line refuses ({count} message{plural}): the command exits "
            "with status 2."
        )
    chain, name = [], parents.get(error, "")
    while name:
        if not name.startswith("_"):
            chain.append(name)
        name = parents.get(name, "")
    return f"A subclass of {', '.join(chain)} ({count} message{plural})."


def setup(app: Any) -> dict[str, Any]:
    """Registers ``error-catalogue``: the full catalogue, one section per class."""
    # The walk above needs no docutils: the tests run without Sphinx.
    from docutils import nodes  # type: ignore[import-untyped,unused-ignore]  # noqa: PLC0415
    from sphinx.util.docutils import SphinxDirective  # noqa: PLC0415

    repository = Path(app.confdir).parent

    class ErrorCatalogue(SphinxDirective):
        """Every message of every class, with the module and line that raises it."""

        def run(self) -> list[nodes.Node]:
            for path in sorted((repository / "python" / "planarcal").rglob("*.py")):
                self.env.note_dependency(str(path))
            parents = error_classes(repository / "python" / "planarcal")
            out: list[nodes.Node] = []
            for error, group in catalogue(repository).items():
                title = "Candidates refused" if error == REFUSAL else error
                section = nodes.section(ids=[f"catalogue-{nodes.make_id(title)}"])
                section += nodes.title(text=title)
                section += nodes.paragraph(text=_about(error, parents, len(group)))
                items = nodes.bullet_list()
                for site in group:
                    paragraph = nodes.paragraph()
                    paragraph += nodes.literal(text=site.message or "(no message)")
                    paragraph += nodes.Text(f" ({site.module}, line {site.line})")
                    items += nodes.list_item("", paragraph)
                section += items
                out.append(section)
            return out

    app.add_directive("error-catalogue", ErrorCatalogue)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}

"""Recipe framework: one recipe per paper figure/table, registered as data.

A recipe is a function decorated with :func:`recipe`; it lives in
``reproductions/<paper>/<something>.py`` and is discovered automatically. It receives a
:class:`RecipeContext` and writes its outputs through it, so that every result gets

* data (CSV, optionally Parquet) and pictures (PNG) under ``results/<paper>/``,
* a provenance record ``results/<paper>/<id>.json`` (git SHA, package versions, CPU, seed,
  backend, quick/full, elapsed time, list of outputs),
* a paper-vs-ours table (``ctx.compare``) printed to the terminal and collected by
  ``pfbench report`` into ``results/REPORT.md``.

Example::

    from pfbench.recipes import recipe

    @recipe("embedded:fig5", aliases=("fig5",), title="Platform timing",
            quick_cost="~1 min", full_cost="~5 min",
            options={"repeats": (int, "timed repetitions (quick 5, full 21)", COUNT)})
    def fig5(ctx):
        reps = ctx.option("repeats", 21 if ctx.full else 5)
        df = ...
        ctx.write_table("fig5", df)
        ctx.compare("D(O) at M=N=1000", ours=3050.0, paper=3112.0, unit="ms")

Options
-------
A recipe declares every ``--option KEY=VALUE`` it reads in ``@recipe(options=...)``: key ->
(type, help, rule) with type int, float, bool, str or list and a rule of :mod:`pfbench.ranges`
(``(float, "variance", POSITIVE)``, ``(str, "model", OneOf("eq52", "eq54"))``,
``(list, "particle counts", ListOf(int, COUNT))``); ``pfbench options ID`` shows the table. Before a
recipe runs, an unknown key is an :class:`~pfbench.errors.InputError` listing the valid ones, a
declared type is checked (with :func:`pfbench.options.typed`: ``runs=2.7`` is not an int) and so is
the rule (``Q=-1`` for a variance is one line, before any work). Reading an undeclared
key (``ctx.option``, ``ctx.options[...]``, ``in``, ``.get``) is a bug in the recipe and raises
``RuntimeError``, so the declarations cannot rot. A recipe that reads ``--data FILE`` says
``reads_data=True``; ``--data`` for any other recipe is an InputError.

Result sets are all-or-nothing
------------------------------
:func:`run` holds an exclusive lock ``results/<paper>/.<name>.lock`` (:func:`pfbench.procs.exclusive_lock`:
a second identical ``pfbench reproduce`` on the same ``--out`` is refused naming the holder's PID;
the kernel drops the lock of a killed run, so the next run takes it over). The recipe writes every
artefact (``ctx.write_table``/``write_figure``/``write_json``) into a staging directory
``results/<paper>/.<name>.staging@<pid>/``; only when the recipe has finished are the artefacts
hashed (SHA-256), moved into ``results/<paper>/``, and the provenance record ``<name>.json``
written LAST with an ``"artefacts": {file: sha256}`` map. A run killed at any moment therefore
leaves either the previous complete set (plus a staging directory that the next run removes), or
new artefacts beside an older record whose checksums no longer match them -- which
:func:`write_report` reports as damaged, as it does a record that is not valid JSON or an artefact
that is missing. Recipes with no result are listed as not run.
"""
from __future__ import annotations

import importlib
import json
import math
import os
import pkgutil
import re
import shutil
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from . import io
from .errors import InputError, PfbenchError  # noqa: F401 - PfbenchError re-exported for recipes
from .options import check_known, did_you_mean, typed
from .procs import exclusive_lock, lock_path
from .provenance import provenance
from .ranges import ListOf, Range

PAPERS = {
    "embedded": "Particle filter on an STM32F4 ([Embedded])",
    "multipdf": "MultiPDF particle filter ([MultiPDF])",
    "thesis": "Particle filters for optimal control under uncertainty ([Thesis])",
    "rtd": "Kalman filter for a resistance temperature detector ([RTD])",
}
DEFAULT_PAPER = "embedded"


@dataclass(frozen=True)
class RecipeOption:
    """One declared recipe option: ``type`` is int, float, bool, str, list or None (any parsed
    value); ``rule`` (:mod:`pfbench.ranges`: a Range, OneOf or ListOf) the values it allows."""

    key: str
    help: str
    type: type | None = None
    rule: Any = None

    @property
    def type_name(self) -> str:
        return self.type.__name__ if self.type is not None else "any"

    @property
    def range_text(self) -> str:
        """What the rule allows, e.g. ``> 0`` or ``one of eq52, eq54`` ("" without a rule)."""
        return "" if self.rule is None else str(self.rule)

    def check(self, value, kind=None):
        """``value`` typed (as ``kind``, default the declared type; see :func:`typed`) and
        checked against the rule: an InputError ``--option KEY=VALUE: ...`` otherwise."""
        what = f"--option {self.key}={_text(value)}"
        if isinstance(self.rule, ListOf):
            return self.rule.check(value, what)
        value = typed(value, kind or self.type, what)
        return value if self.rule is None else self.rule.check(value, what)

    def as_dict(self) -> dict:
        return {"help": self.help, "type": self.type_name, "range": self.range_text}


def _declare(options) -> tuple[RecipeOption, ...]:
    """``options`` of :func:`recipe` as RecipeOptions: key -> "help", (type, "help") or
    (type, "help", rule); a list option is (list, "help", ListOf(...)). Numbers need a Range."""
    out = []
    for key, spec in dict(options or {}).items():
        kind, text, rule = (tuple(spec) + (None,))[:3] if isinstance(spec, tuple) else (None, spec, None)
        if not str(key).isidentifier() or not isinstance(text, str) or not text.strip():
            raise ValueError(f"recipe option {key!r}: declare it as key -> 'help' or (type, 'help', rule)")
        if kind not in (None, int, float, bool, str, list):
            raise ValueError(f"recipe option {key!r}: type must be int, float, bool, str, list or None")
        if (kind is list) != isinstance(rule, ListOf) or (kind in (int, float) and rule is not None
                                                           and not isinstance(rule, Range)):
            raise ValueError(f"recipe option {key!r}: a list needs a ListOf rule, a number a Range")
        if rule is not None and not callable(getattr(rule, "check", None)):
            raise ValueError(f"recipe option {key!r}: the rule must be a Range, OneOf or ListOf")
        out.append(RecipeOption(str(key), " ".join(text.split()), kind, rule))
    return tuple(out)


@dataclass(frozen=True)
class Recipe:
    id: str                      # "paper:name"
    func: Callable[["RecipeContext"], Any]
    title: str
    aliases: tuple[str, ...] = ()
    quick_cost: str = ""
    full_cost: str = ""
    needs: tuple[str, ...] = ()  # optional tools, e.g. ("mcu-tools",); recipe skipped by --all if missing
    options: tuple[RecipeOption, ...] = ()  # the --option keys it reads
    reads_data: bool = False     # whether it accepts --data FILE

    @property
    def option_keys(self) -> tuple[str, ...]:
        return tuple(o.key for o in self.options)

    def declared(self, key: str) -> RecipeOption:
        """The declaration of option ``key``; RuntimeError (a bug in the recipe) if undeclared."""
        for o in self.options:
            if o.key == key:
                return o
        raise RuntimeError(f"recipe {self.id} reads option {key!r} but does not declare it in "
                           f"@recipe(options=...) (declared: {', '.join(self.option_keys) or 'none'})")

    def check_options(self, options: dict) -> dict:
        """``options`` validated against the declarations: unknown keys, badly typed values and
        values outside the declared rule are InputErrors; returns the options with declared types
        applied (a list option as a list)."""
        check_known(options, self.option_keys, f"an option of recipe {self.id}")
        return {k: self.declared(k).check(v) for k, v in options.items()}

    @property
    def paper(self) -> str:
        return self.id.split(":", 1)[0]

    @property
    def name(self) -> str:
        return self.id.split(":", 1)[1]


_REGISTRY: dict[str, Recipe] = {}
_DISCOVERED = False


def _text(value) -> str:
    """An option value as the text a user would have typed."""
    return value if isinstance(value, str) else json.dumps(value, default=str)


def recipe(id: str, *, title: str, aliases: Iterable[str] = (), quick_cost: str = "",
           full_cost: str = "", needs: Iterable[str] = (), options: dict | None = None,
           reads_data: bool = False):
    """Register a recipe function under ``id`` ("paper:name").

    ``options``: every ``--option`` key the recipe reads, key -> (type, "help", rule) (module
    docstring; key -> "help" or (type, "help") declares no rule, for throw-away recipes);
    ``reads_data``: the recipe accepts ``--data FILE``.
    """
    if ":" not in id or id.split(":", 1)[0] not in PAPERS:
        raise ValueError(f"recipe id must be '<paper>:<name>' with paper in {sorted(PAPERS)}: {id!r}")
    declared = _declare(options)

    def deco(func):
        _REGISTRY[id] = Recipe(id=id, func=func, title=title, aliases=tuple(aliases),
                               quick_cost=quick_cost, full_cost=full_cost, needs=tuple(needs),
                               options=declared, reads_data=bool(reads_data))
        return func

    return deco


def discover() -> dict[str, Recipe]:
    """Import every module under :mod:`pfbench.reproductions` so that their recipes register.

    The recipes live in the ``reproductions/`` folder at the top of the repository; in a checkout
    ``pfbench/reproductions`` is a link to it, and the wheel installs it as ``pfbench.reproductions``
    (never as a top-level ``reproductions``, a name other packages may use)."""
    global _DISCOVERED
    if not _DISCOVERED:
        from . import reproductions

        for mod in pkgutil.walk_packages(reproductions.__path__, prefix=f"{reproductions.__name__}."):
            importlib.import_module(mod.name)
        _DISCOVERED = True
    return dict(sorted(_REGISTRY.items()))


def resolve(name: str) -> Recipe:
    """Find a recipe by full id, alias, or bare name (bare names default to the embedded paper)."""
    reg = discover()
    if name in reg:
        return reg[name]
    for rec in reg.values():
        if name in rec.aliases:
            return rec
    if ":" not in name and f"{DEFAULT_PAPER}:{name}" in reg:
        return reg[f"{DEFAULT_PAPER}:{name}"]
    matches = [r for r in reg.values() if r.name == name]
    if len(matches) == 1:
        return matches[0]
    if len(matches) > 1:
        ids = ", ".join(r.id for r in matches)
        raise InputError(f"recipe name {name!r} is ambiguous: use one of {ids}")
    hint = did_you_mean(name, list(reg) + [a for r in reg.values() for a in r.aliases]
                        + [r.name for r in reg.values()])
    raise InputError(f"unknown recipe {name!r}{hint} (`pfbench list` shows the recipes)")


def same_name(name: str, rec: Recipe) -> list[str]:
    """The IDs of the other papers' recipes called ``name`` when ``name`` is bare and picked
    ``rec`` (``fig5`` is ``embedded:fig5``; ``multipdf:fig5`` and ``rtd:fig5`` exist too)."""
    if ":" in name:
        return []
    return [r.id for r in discover().values() if r.name == name and r is not rec]


def select(paper: str | None = None) -> list[Recipe]:
    """Every registered recipe, or those of ``paper``; an unknown paper is an InputError listing
    the papers (a selector that matches nothing is an error, never an empty run)."""
    reg = discover()
    if paper is None:
        return list(reg.values())
    if paper not in PAPERS:
        hint = did_you_mean(paper, PAPERS)
        raise InputError(f"--paper {paper!r}: no such paper{hint} (papers: {', '.join(PAPERS)})")
    recs = [r for r in reg.values() if r.paper == paper]
    if not recs:
        raise InputError(f"--paper {paper}: no recipes registered for this paper")
    return recs


def needs_met(needs: Iterable[str]) -> bool:
    """Whether the optional tools a recipe needs (:attr:`Recipe.needs`) are installed."""
    for need in needs:
        if need == "mcu-tools":
            try:
                from .mcu import toolchain
            except ImportError:
                return False
            if not toolchain.available():
                return False
        else:
            return False
    return True


def needs_hint(needs: Iterable[str]) -> str:
    """How to install what a recipe needs, e.g. "needs `make mcu-tools`"."""
    return "needs " + ", ".join(f"`make {n}`" for n in needs)


@dataclass
class Comparison:
    quantity: str
    ours: Any
    paper: Any = None
    unit: str = ""
    note: str = ""

    @property
    def deviation(self) -> float | None:
        """Relative deviation (ours - paper) / |paper| when both are numbers."""
        try:
            o, p = float(self.ours), float(self.paper)
        except (TypeError, ValueError):
            return None
        if p == 0 or not math.isfinite(o) or not math.isfinite(p):
            return None
        return (o - p) / abs(p)

    def as_dict(self) -> dict:
        return {"quantity": self.quantity, "ours": self.ours, "paper": self.paper,
                "unit": self.unit, "deviation": self.deviation, "note": self.note}


class RecipeOptions(Mapping):
    """The ``--option`` values of a run, read-only; looking up a key the recipe did not declare
    raises RuntimeError (see :meth:`Recipe.declared`)."""

    def __init__(self, recipe: Recipe, values: dict):
        self._recipe, self._values = recipe, dict(values)

    def __getitem__(self, key):
        self._recipe.declared(key)
        return self._values[key]

    def __iter__(self):
        return iter(self._values)

    def __len__(self):
        return len(self._values)

    def __repr__(self):
        return f"RecipeOptions({self._values!r})"


@dataclass
class RecipeContext:
    """What a recipe gets: options, output helpers, and the paper-vs-ours ledger."""

    recipe: Recipe
    full: bool = False
    backend: str = "numba"
    seed: int = 0
    out_root: Path = Path("results")
    data: Path | None = None
    options: Mapping = field(default_factory=dict)
    quiet: bool = False
    outputs: list[str] = field(default_factory=list)
    comparisons: list[Comparison] = field(default_factory=list)
    claims: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    extra: dict = field(default_factory=dict)
    stage_dir: Path | None = None   # set by run(): artefacts are written here, then moved
    staged: dict = field(default_factory=dict)   # final path (str) -> staged path

    def __post_init__(self):
        if not isinstance(self.options, RecipeOptions):
            self.options = RecipeOptions(self.recipe, self.options)

    @property
    def out_dir(self) -> Path:
        return Path(self.out_root) / self.recipe.paper

    def path(self, filename: str) -> Path:
        """The final path of artefact ``filename`` (``results/<paper>/<filename>``)."""
        return self.out_dir / filename

    def _target(self, filename: str) -> Path:
        """Where artefact ``filename`` is written now: the staging directory during :func:`run`."""
        return (self.stage_dir if self.stage_dir is not None else self.out_dir) / filename

    def _record(self, written: Path) -> Path:
        final = self.path(written.name)
        if str(final) in self.outputs:
            raise RuntimeError(f"recipe {self.recipe.id} writes {written.name} twice")  # a bug
        self.outputs.append(str(final))
        if written != final:
            self.staged[str(final)] = written
        return written

    # ----- options ---------------------------------------------------------------------
    def option(self, key: str, default, cast=None):
        """Recipe option ``key`` (``--option KEY=VALUE``), or ``default`` when not given.

        The value is checked with :func:`pfbench.options.typed` against ``cast`` (default: the
        declared type, else the type of ``default``): ``runs=2.7`` for an int is an InputError,
        never 2; then against the declared rule (a list option comes back as a list). ``key``
        must be declared in ``@recipe(options=...)`` (RuntimeError otherwise).
        """
        decl = self.recipe.declared(key)
        if key not in self.options:
            return default
        return decl.check(self.options[key], cast or decl.type or (type(default) if default is not None else None))

    # ----- outputs -------------------------------------------------------------------
    # Each writer returns the path the file has now (in the staging directory while the recipe
    # runs); ``outputs`` lists the final paths.
    def write_table(self, name: str, frame, parquet: bool = False) -> Path:
        """Write a DataFrame as ``<name>.csv`` (and ``.parquet`` if asked)."""
        p = self._record(io.write_csv(self._target(f"{name}.csv"), frame))
        if parquet:
            self._record(io.write_parquet(self._target(f"{name}.parquet"), frame))
        return p

    def write_figure(self, name: str, fig) -> Path:
        return self._record(io.write_figure(self._target(f"{name}.png"), fig))

    def write_json(self, name: str, obj) -> Path:
        """Write ``obj`` as strict JSON ``<name>.data.json`` (see :mod:`pfbench.io`)."""
        return self._record(io.write_json(self._target(f"{name}.data.json"), obj))

    # ----- ledger ----------------------------------------------------------------------
    def compare(self, quantity: str, ours, paper=None, unit: str = "", note: str = "") -> None:
        """Record one paper-vs-ours line (paper may be None or a claim in words)."""
        self.comparisons.append(Comparison(quantity, ours, paper, unit, note))

    def claim(self, claim: str, where: str, quantity: str, outcome, paper=None, note: str = "", *,
              kind: str = "finding", reading: str = "", others=()) -> None:
        """Record one sentence of the paper that this recipe tests, with its computed verdict.

        ``claim``: the sentence, quoted or paraphrased; ``where``: its location ("[Thesis] §4.4.5,
        Fig. 4.9"); ``quantity``: what we measure; ``outcome``: a :class:`pfbench.verdicts.Outcome`
        from one of the rules of :mod:`pfbench.verdicts` (never a typed verdict); ``paper``: the
        paper's value or direction as it states it; ``note``: what the reader should know (for
        kind ``by construction``, the reason it holds whatever the data: required).

        ``kind``: :data:`~pfbench.verdicts.FINDING` (scored), :data:`~pfbench.verdicts.SETUP` or
        :data:`~pfbench.verdicts.CONSTRUCTION` (shown, never scored). One sentence is one finding:
        recording the same (claim, where) finding twice is a bug in the recipe (RuntimeError).
        Where the sentence admits several readings, ``reading`` says which one ``outcome`` scores
        and why it is the primary one, and ``others`` (:class:`pfbench.verdicts.Reading`) are the
        other readings, shown beneath it as sensitivity rows; the claim is marked "depends on
        reading" when their verdicts differ from the primary one's.
        """
        from .verdicts import AGREE, CONSTRUCTION, FINDING, KINDS, Outcome, Reading

        if not isinstance(outcome, Outcome):
            raise TypeError("claim() needs an Outcome from pfbench.verdicts (verdicts are computed)")
        if kind not in KINDS:
            raise ValueError(f"claim kind must be one of {KINDS}, got {kind!r}")
        if kind == CONSTRUCTION and not note.strip():
            raise ValueError(f"claim {claim!r}: a 'by construction' claim needs the reason in note=")
        others = list(others)
        if not all(isinstance(o, Reading) for o in others):
            raise TypeError("claim(others=...) takes pfbench.verdicts.Reading rows")
        if others and not reading.strip():
            raise ValueError(f"claim {claim!r}: with other readings, say which reading is primary "
                             "and why (reading=...)")
        if (outcome.verdict == AGREE and outcome.interval is not None and outcome.band is not None
                and not outcome.band[0] <= outcome.interval[0] <= outcome.interval[1] <= outcome.band[1]):
            raise RuntimeError(f"claim {claim!r} agrees although its interval {outcome.interval} leaves its "
                               f"band {outcome.band}: build outcomes with the rules of pfbench.verdicts")
        if kind == FINDING and any(c["kind"] == FINDING and c["claim"] == claim and c["where"] == where
                                   for c in self.claims):
            raise RuntimeError(f"recipe {self.recipe.id} scores the sentence {claim!r} ({where}) twice: "
                               "one sentence is one finding; pass other readings as others=")
        self.claims.append({"claim": claim, "where": where, "quantity": quantity, "paper": paper,
                            "note": note, "kind": kind, "reading": reading,
                            "sensitivity": [o.as_dict() for o in others],
                            "depends_on_reading": any(o.outcome.verdict != outcome.verdict for o in others),
                            **outcome.as_dict()})

    def note(self, text: str) -> None:
        """A sentence for the report: what differs from the paper and why."""
        self.notes.append(text)

    def progress(self, iterable=None, total: int | None = None, desc: str = ""):
        """A progress bar (to stderr) for long work, unless quiet or stderr is not a terminal."""
        from .progress import progress_bar

        return progress_bar(iterable, show=not self.quiet, total=total, desc=desc or self.recipe.id,
                            leave=False, dynamic_ncols=True)

    def log(self, text: str) -> None:
        if not self.quiet:
            print(text, file=sys.stderr)


def cost_seconds(cost: str) -> float | None:
    """A recipe's cost text in seconds (``"~2 s"`` -> 2.0, ``"~3 min (+~1 min ...)"`` -> 180.0, the
    leading estimate), for ``pfbench list --json``; None if the text does not start that way."""
    m = re.match(r"~?\s*(\d+(?:\.\d+)?)\s*(s|min|h)\b", cost.strip())
    return None if m is None else float(m.group(1)) * {"s": 1, "min": 60, "h": 3600}[m.group(2)]


def format_comparisons(comparisons: list[Comparison]) -> str:
    """Plain-text table: quantity | ours | paper | deviation | note."""
    if not comparisons:
        return "(no paper-vs-ours comparisons recorded)"

    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        return "-" if v is None else str(v)

    rows = [("quantity", "ours", "paper", "dev", "note")]
    for c in comparisons:
        dev = c.deviation
        rows.append((c.quantity + (f" [{c.unit}]" if c.unit else ""), fmt(c.ours), fmt(c.paper),
                     f"{dev:+.1%}" if dev is not None else "", c.note))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    lines = []
    for r in rows:
        lines.append("  ".join(r[i].ljust(widths[i]) for i in range(4)) + ("  " + r[4] if r[4] else ""))
    return "\n".join(lines)


def check_data(recs: list[Recipe], data) -> None:
    """An InputError if ``data`` (``--data FILE``) is given but none of ``recs`` reads data."""
    if data and not any(r.reads_data for r in recs):
        which = recs[0].id if len(recs) == 1 else "none of the selected recipes"
        readers = ", ".join(r.id for r in discover().values() if r.reads_data) or "none"
        raise InputError(f"--data: {which} reads no data (recipes that take a log: {readers})")


STAGING = ".staging@"   # results/<paper>/.<name>.staging@<pid>/


def _lock_path(out_dir: Path, name: str) -> Path:
    return lock_path(out_dir / f".{name}")


def _leftovers(out_dir: Path, name: str) -> list[Path]:
    """Staging directories and temporary files of recipe ``name`` left by an interrupted run."""
    try:
        entries = list(out_dir.iterdir())
    except OSError:
        return []
    stage, tmp = f".{name}{STAGING}", f".{name}.json."
    return [e for e in entries if (e.name.startswith(stage) and e.name[len(stage):].isdigit())
            or (e.name.startswith(tmp) and e.name.endswith(".tmp"))]


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def _commit(ctx: RecipeContext, record: dict) -> None:
    """Move the staged artefacts into place and write the provenance record last, with the
    SHA-256 of every artefact (see the module docstring)."""
    out_dir = ctx.out_dir
    staged, artefacts = [], {}
    for out in ctx.outputs:
        final = Path(out)
        src = ctx.staged.get(str(out), final)   # else written in place (e.g. a resumable store)
        if src != final:
            staged.append((src, final))
        try:
            rel = final.relative_to(out_dir).as_posix()
        except ValueError:
            rel = str(final)
        try:
            artefacts[rel] = io.sha256(src)
        except OSError as exc:
            raise RuntimeError(f"recipe {ctx.recipe.id} lists output {out} but it cannot be "
                               f"read: {exc}") from None   # a bug in the recipe
    record["artefacts"] = artefacts
    for src, final in staged:
        try:
            os.replace(src, final)
        except OSError as exc:
            raise io.output_error(final, exc) from None
    io.write_json(ctx.path(f"{ctx.recipe.name}.json"), record)


def code_fingerprint(rec: Recipe) -> str:
    """Hash of the code behind a recipe's numbers: the whole pfbench package
    (:func:`pfbench.backends.cache.package_fingerprint`) and the recipe's paper folder."""
    import hashlib

    from . import reproductions
    from .backends.cache import package_fingerprint

    h = hashlib.sha256(package_fingerprint().encode())
    folder = Path(reproductions.__file__).resolve().parent / rec.paper
    for f in sorted(folder.rglob("*.py")):
        h.update(f.name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:16]


def up_to_date(rec: Recipe, *, out_root, full: bool, seed: int, backend: str, options: dict,
               data=None) -> bool:
    """Whether ``results/<paper>/<name>.json`` verifies against its artefacts and was made by this
    code (:func:`code_fingerprint`) with the same mode, seed, backend, options and data: then
    ``reproduce --all`` skips it, which is how an interrupted batch resumes."""
    from .report import verify

    path = Path(out_root) / rec.paper / f"{rec.name}.json"
    if not path.exists():
        return False
    record, problems = verify(path, rec.id)
    if record is None or problems:
        return False
    want = {"mode": "full" if full else "quick", "seed": seed, "backend": backend,
            "options": dict(options), "data": str(Path(data)) if data else None, "code": code_fingerprint(rec)}
    return all(record.get(k) == v for k, v in want.items())


def run(rec: Recipe, *, full: bool = False, backend: str = "numba", seed: int = 0,
        out_root: str | Path = "results", data: str | Path | None = None, quiet: bool = False,
        options: dict | None = None) -> RecipeContext:
    """Run one recipe and write its result set (artefacts, then the provenance record). Returns
    the filled context.

    Options are validated first (:meth:`Recipe.check_options`), and ``data`` is refused for a
    recipe that does not declare ``reads_data``, so bad input fails before any work. The output
    is locked for the whole run (an InputError naming the PID if another process writes it) and
    written all-or-nothing (module docstring); leftovers of an interrupted run are removed first.
    """
    opts = rec.check_options(dict(options or {}))
    check_data([rec], data)
    out_dir = io.make_dirs(Path(out_root) / rec.paper)
    with exclusive_lock(out_dir / f".{rec.name}", f"{out_dir / rec.name}.* (recipe {rec.id})"):
        for left in _leftovers(out_dir, rec.name):
            _remove(left)
        stage = io.make_dirs(out_dir / f".{rec.name}{STAGING}{os.getpid()}")
        try:
            ctx = RecipeContext(recipe=rec, full=full, backend=backend, seed=seed,
                                out_root=Path(out_root), data=Path(data) if data else None,
                                options=opts, quiet=quiet, stage_dir=stage)
            t0 = time.perf_counter()
            rec.func(ctx)
            elapsed = time.perf_counter() - t0
            record = provenance(
                recipe=rec.id, title=rec.title, mode="full" if full else "quick", backend=backend,
                code=code_fingerprint(rec),
                seed=seed, data=str(ctx.data) if ctx.data else None, options=dict(ctx.options),
                elapsed_s=round(elapsed, 3), outputs=ctx.outputs,
                comparisons=[c.as_dict() for c in ctx.comparisons], claims=ctx.claims, notes=ctx.notes,
                extra=ctx.extra)
            _commit(ctx, record)
        finally:
            _remove(stage)
    ctx.stage_dir = None
    ctx.extra["elapsed_s"] = elapsed
    return ctx

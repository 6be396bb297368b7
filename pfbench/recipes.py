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
            options={"repeats": (int, "timed repetitions (quick 5, full 21)")})
    def fig5(ctx):
        reps = ctx.option("repeats", 21 if ctx.full else 5)
        df = ...
        ctx.write_table("fig5", df)
        ctx.compare("D(O) at M=N=1000", ours=3050.0, paper=3112.0, unit="ms")

Options
-------
A recipe declares every ``--option KEY=VALUE`` it reads in ``@recipe(options=...)``: key -> one-line
help, or key -> (type, help) with type int, float, bool or str. Before a recipe runs, an unknown
key is an :class:`~pfbench.errors.InputError` listing the valid ones and a declared type is
checked (with :func:`pfbench.options.typed`: ``runs=2.7`` is not an int). Reading an undeclared
key (``ctx.option``, ``ctx.options[...]``, ``in``, ``.get``) is a bug in the recipe and raises
``RuntimeError``, so the declarations cannot rot. A recipe that reads ``--data FILE`` says
``reads_data=True``; ``--data`` for any other recipe is an InputError.
"""
from __future__ import annotations

import importlib
import json
import math
import pkgutil
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable

from . import io
from .errors import InputError, PfbenchError  # noqa: F401 - PfbenchError re-exported for recipes
from .options import check_known, typed
from .provenance import provenance

PAPERS = {
    "embedded": "Particle filter on an STM32F4 ([Embedded])",
    "multipdf": "MultiPDF particle filter ([MultiPDF])",
    "thesis": "Particle filters for optimal control under uncertainty ([Thesis])",
    "rtd": "Kalman filter for a resistance temperature detector ([RTD])",
}
DEFAULT_PAPER = "embedded"


@dataclass(frozen=True)
class RecipeOption:
    """One declared recipe option: ``type`` is int, float, bool, str or None (any parsed value)."""

    key: str
    help: str
    type: type | None = None

    @property
    def type_name(self) -> str:
        return self.type.__name__ if self.type is not None else "any"

    def as_dict(self) -> dict:
        return {"help": self.help, "type": self.type_name}


def _declare(options) -> tuple[RecipeOption, ...]:
    out = []
    for key, spec in dict(options or {}).items():
        kind, text = spec if isinstance(spec, tuple) else (None, spec)
        if not str(key).isidentifier() or not isinstance(text, str) or not text.strip():
            raise ValueError(f"recipe option {key!r}: declare it as key -> 'help' or (type, 'help')")
        if kind not in (None, int, float, bool, str):
            raise ValueError(f"recipe option {key!r}: type must be int, float, bool, str or None")
        out.append(RecipeOption(str(key), " ".join(text.split()), kind))
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
        """``options`` validated against the declarations: unknown keys and badly typed values
        are InputErrors; returns the options with declared types applied."""
        check_known(options, self.option_keys, f"recipe {self.id}")
        return {k: typed(v, self.declared(k).type, f"--option {k}={_text(v)}") for k, v in options.items()}

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

    ``options``: every ``--option`` key the recipe reads, key -> "one-line help" or
    key -> (type, "help"); ``reads_data``: the recipe accepts ``--data FILE``.
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
    """Import every module under ``reproductions`` so that their recipes register."""
    global _DISCOVERED
    if not _DISCOVERED:
        import reproductions

        for mod in pkgutil.walk_packages(reproductions.__path__, prefix="reproductions."):
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
    raise InputError(f"unknown recipe {name!r}; `pfbench list` shows the recipes")


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
    notes: list[str] = field(default_factory=list)
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        if not isinstance(self.options, RecipeOptions):
            self.options = RecipeOptions(self.recipe, self.options)

    @property
    def out_dir(self) -> Path:
        return Path(self.out_root) / self.recipe.paper

    def path(self, filename: str) -> Path:
        return self.out_dir / filename

    def _record(self, path: Path) -> Path:
        self.outputs.append(str(path))
        return path

    # ----- options ---------------------------------------------------------------------
    def option(self, key: str, default, cast=None):
        """Recipe option ``key`` (``--option KEY=VALUE``), or ``default`` when not given.

        The value is checked with :func:`pfbench.options.typed` against ``cast`` (default: the
        declared type, else the type of ``default``): ``runs=2.7`` for an int is an InputError,
        never 2. ``key`` must be declared in ``@recipe(options=...)`` (RuntimeError otherwise).
        """
        decl = self.recipe.declared(key)
        if key not in self.options:
            return default
        value = self.options[key]
        kind = cast or decl.type or (type(default) if default is not None else None)
        return typed(value, kind, f"--option {key}={_text(value)}")

    # ----- outputs -------------------------------------------------------------------
    def write_table(self, name: str, frame, parquet: bool = False) -> Path:
        """Write a DataFrame as ``<name>.csv`` (and ``.parquet`` if asked)."""
        p = self._record(io.write_csv(self.path(f"{name}.csv"), frame))
        if parquet:
            self._record(io.write_parquet(self.path(f"{name}.parquet"), frame))
        return p

    def write_figure(self, name: str, fig) -> Path:
        return self._record(io.write_figure(self.path(f"{name}.png"), fig))

    def write_json(self, name: str, obj) -> Path:
        return self._record(io.write_json(self.path(f"{name}.data.json"), obj))

    # ----- ledger ----------------------------------------------------------------------
    def compare(self, quantity: str, ours, paper=None, unit: str = "", note: str = "") -> None:
        """Record one paper-vs-ours line (paper may be None or a claim in words)."""
        self.comparisons.append(Comparison(quantity, ours, paper, unit, note))

    def note(self, text: str) -> None:
        """A sentence for the report: what differs from the paper and why."""
        self.notes.append(text)

    def progress(self, iterable=None, total: int | None = None, desc: str = ""):
        """A tqdm progress bar (to stderr), shown for long work unless quiet."""
        from tqdm.auto import tqdm

        return tqdm(iterable, total=total, desc=desc or self.recipe.id, disable=self.quiet,
                    file=sys.stderr, leave=False, dynamic_ncols=True)

    def log(self, text: str) -> None:
        if not self.quiet:
            print(text, file=sys.stderr)


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


def run(rec: Recipe, *, full: bool = False, backend: str = "numba", seed: int = 0,
        out_root: str | Path = "results", data: str | Path | None = None, quiet: bool = False,
        options: dict | None = None) -> RecipeContext:
    """Run one recipe and write its provenance record. Returns the filled context.

    Options are validated first (:meth:`Recipe.check_options`), and ``data`` is refused for a
    recipe that does not declare ``reads_data``, so bad input fails before any work.
    """
    opts = rec.check_options(dict(options or {}))
    check_data([rec], data)
    ctx = RecipeContext(recipe=rec, full=full, backend=backend, seed=seed, out_root=Path(out_root),
                        data=Path(data) if data else None, options=opts, quiet=quiet)
    t0 = time.perf_counter()
    rec.func(ctx)
    elapsed = time.perf_counter() - t0
    record = provenance(
        recipe=rec.id, title=rec.title, mode="full" if full else "quick", backend=backend,
        seed=seed, data=str(ctx.data) if ctx.data else None, options=dict(ctx.options),
        elapsed_s=round(elapsed, 3), outputs=ctx.outputs,
        comparisons=[c.as_dict() for c in ctx.comparisons], notes=ctx.notes, extra=ctx.extra)
    io.write_json(ctx.path(f"{rec.name}.json"), record)
    ctx.extra["elapsed_s"] = elapsed
    return ctx


def write_report(out_root: str | Path = "results") -> Path:
    """Regenerate ``results/REPORT.md`` from every provenance record under ``out_root``."""
    out_root = Path(out_root)
    records = []
    for paper in PAPERS:
        for p in sorted((out_root / paper).glob("*.json")):
            if p.name.endswith(".data.json"):
                continue
            try:
                rec = json.loads(p.read_text())
            except (OSError, ValueError):
                continue
            if isinstance(rec, dict) and "recipe" in rec:
                records.append(rec)
    lines = ["# pfbench results report", "",
             "Generated by `pfbench report` from the provenance records under `results/`.", ""]
    for paper, title in PAPERS.items():
        recs = [r for r in records if r["recipe"].startswith(paper + ":")]
        if not recs:
            continue
        lines += [f"## {paper}: {title}", ""]
        for r in recs:
            lines.append(f"### `{r['recipe']}`: {r.get('title', '')}")
            lines.append("")
            lines.append(f"mode {r.get('mode')}, backend {r.get('backend')}, seed {r.get('seed')}, "
                         f"{r.get('elapsed_s')} s, git {str(r.get('git_sha'))[:12]}, "
                         f"{r.get('created_utc')}")
            lines.append("")
            comps = r.get("comparisons") or []
            if comps:
                lines.append("| quantity | ours | paper | deviation | note |")
                lines.append("|---|---|---|---|---|")
                for c in comps:
                    dev = c.get("deviation")
                    q = c["quantity"] + (f" [{c['unit']}]" if c.get("unit") else "")
                    ours, pap = c.get("ours"), c.get("paper")
                    ours = f"{ours:.4g}" if isinstance(ours, float) else ours
                    pap = f"{pap:.4g}" if isinstance(pap, float) else ("-" if pap is None else pap)
                    lines.append(f"| {q} | {ours} | {pap} | "
                                 f"{'' if dev is None else f'{dev:+.1%}'} | {c.get('note', '')} |")
                lines.append("")
            for n in r.get("notes") or []:
                lines.append(f"- {n}")
            outs = [Path(o).name for o in r.get("outputs") or []]
            if outs:
                lines.append("")
                lines.append("Outputs: " + ", ".join(f"`{o}`" for o in outs))
            lines.append("")
    return io.write_text(out_root / "REPORT.md", "\n".join(lines) + "\n")

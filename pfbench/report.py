"""``pfbench report``: every result set verified against its checksums, a scorecard of the papers'
claims per paper, and the paper-vs-ours tables, in ``results/REPORT.md`` (and ``--json``)."""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

from . import io
from .errors import PfbenchError
from . import recipes as _recipes
from .recipes import PAPERS, _leftovers, _lock_path, discover, needs_hint
from .verdicts import (AGREE, CONSTRUCTION, DEFINITIONS, DISAGREE, FINDING, KINDS, SETUP,
                       VERDICTS, expected_false)


@dataclass
class Problem:
    """One line of the report's "Not reproduced / damaged" section."""

    recipe: str
    what: str
    redo: str
    damaged: bool = True     # a damaged/incomplete result (a warning; ``report --strict`` fails)

    def line(self) -> str:
        return f"`{self.recipe}`: {self.what}; {self.redo}"


def verify(path: str | Path, recipe_id: str) -> tuple[dict | None, list[str]]:
    """Read the provenance record ``path`` of ``recipe_id`` and check it against the files on
    disk: ``(record or None, [problems])``. A problem is an unreadable/garbage record, a record of
    another recipe, a record without checksums (written before they were recorded), a missing
    artefact or one whose SHA-256 differs from the record's."""
    path = Path(path)
    try:
        rec = io.loads(path.read_text(encoding="utf-8", errors="replace"), str(path))
    except OSError as exc:
        return None, [f"record {path} cannot be read ({exc.strerror or exc})"]
    except PfbenchError as exc:
        return None, [f"record {path} is damaged: {str(exc).split(': ', 1)[-1]}"]
    if not isinstance(rec, dict) or not isinstance(rec.get("recipe"), str):
        return None, [f"record {path} is damaged: not a provenance record"]
    if rec["recipe"] != recipe_id:
        return None, [f"record {path} is damaged: it names recipe {rec['recipe']!r}"]
    arts = rec.get("artefacts")
    if not isinstance(arts, dict):
        return rec, [f"record {path} has no artefact checksums (written by an older pfbench or "
                     "edited): its files cannot be verified"]
    problems, bad = [], []
    for rel, digest in arts.items():
        f = path.parent / rel
        try:
            ok = io.sha256(f) == digest
        except FileNotFoundError:
            problems.append(f"{f} is missing")
            continue
        except OSError as exc:
            problems.append(f"{f} cannot be read ({exc.strerror or exc})")
            continue
        if not ok:
            bad.append(rel)
    if bad:
        problems.append(f"{', '.join(bad)} do{'es' if len(bad) == 1 else ''} not match the record "
                        f"(seed {rec.get('seed')}, {rec.get('created_utc')}): the files were changed "
                        "or a later run was interrupted")
    return rec, problems


def _reproduce(rid: str, out_root: Path, rec: dict | None = None) -> str:
    """The command that redoes ``rid`` where it was: with ``--out`` (when not the default) and the
    record's mode, backend, seed and options (a bare `pfbench reproduce ID` would write to results/
    with the defaults)."""
    words = ["pfbench reproduce", rid]
    if out_root != Path("results"):
        words.append(f"--out {out_root}")
    rec = rec or {}
    if rec.get("mode") == "full":
        words.append("--full")
    if rec.get("backend") not in (None, "numba"):
        words.append(f"--backend {rec['backend']}")
    if rec.get("seed") not in (None, 0):
        words.append(f"--seed {rec['seed']}")
    words += [f"--option {k}={v if isinstance(v, str) else json.dumps(v, separators=(',', ':'))}"
              for k, v in (rec.get("options") or {}).items()]
    return " ".join(words)


def check_results(out_root: str | Path = "results") -> tuple[list[dict], list[Problem]]:
    """Every verified provenance record under ``out_root`` and every problem (damaged or
    incomplete result sets, recipes with no result)."""
    out_root = Path(out_root)
    reg = discover()
    records, problems = [], []
    seen = set()
    for paper in PAPERS:
        d = out_root / paper
        try:
            files = sorted(p for p in d.glob("*.json") if not p.name.endswith(".data.json"))
        except OSError:
            files = []
        for p in files:
            rid = f"{paper}:{p.stem}"
            rec, probs = verify(p, rid)
            if probs and not _locked(d, p.stem):  # a run may have finished its commit meanwhile
                rec, probs = verify(p, rid)
            redo = f"redo: `{_reproduce(rid, out_root, rec)}`"
            if probs and _locked(d, p.stem):  # mid-commit: skipped, not flagged
                problems.append(Problem(rid, "being written by a running `pfbench reproduce` (its lock is "
                                        "held): not checked", "report again when it has finished",
                                        damaged=False))
                seen.add(rid)
                continue
            if rid not in reg and rec is None:
                problems.append(Problem(rid, "; ".join(probs) + " (no such recipe)", "remove the file"))
                continue
            seen.add(rid)
            if probs:
                problems.append(Problem(rid, "; ".join(probs), redo))
            if rec is not None and not probs:
                records.append(rec)
            elif rec is not None:
                rec = dict(rec, damaged=True)
                records.append(rec)
            if any(_leftovers(d, p.stem)) and not _locked(d, p.stem):
                problems.append(Problem(rid, "an interrupted run left a staging directory (the "
                                        "result above is the previous complete one)",
                                        f"it is removed by the next `{_reproduce(rid, out_root, rec)}`",
                                        damaged=False))
    for rid, r in reg.items():
        if rid in seen:
            continue
        if r.needs and not _recipes.needs_met(r.needs):
            problems.append(Problem(rid, f"not run: {needs_hint(r.needs)}",
                                    f"then `{_reproduce(rid, out_root)}`", damaged=False))
        else:
            problems.append(Problem(rid, "not run (no result)", f"run `{_reproduce(rid, out_root)}`",
                                    damaged=False))
    return records, problems


def _locked(out_dir: Path, name: str) -> bool:
    """Whether a run of recipe ``name`` holds its lock now (then its files may be mid-commit: an
    artefact replaced, the record not yet, so a mismatch is no damage)."""
    import fcntl

    try:
        fd = os.open(_lock_path(out_dir, name), os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        return False
    except OSError:
        return True
    finally:
        os.close(fd)


def _kind(c: dict) -> str:
    """A claim's kind (:data:`pfbench.verdicts.KINDS`); records written before kinds existed hold findings."""
    return c.get("kind") or FINDING


def _claims(record: dict) -> list[dict]:
    return [c for c in record.get("claims") or [] if isinstance(c, dict)]


def scored_findings(records: list[dict]) -> tuple[dict[str, list[dict]], list[Problem]]:
    """Per paper, the findings the scorecard counts (one per sentence), and a problem line for each
    sentence that two recipes score (counted once, under the first recipe)."""
    out: dict[str, list[dict]] = {paper: [] for paper in PAPERS}
    seen: dict[tuple, str] = {}
    problems = []
    for r in records:
        paper = r["recipe"].split(":", 1)[0]
        for c in _claims(r):
            if _kind(c) != FINDING or c.get("verdict") not in VERDICTS or paper not in out:
                continue
            key = (paper, str(c.get("where")), str(c.get("claim")))
            if key in seen:
                problems.append(Problem(r["recipe"], f"scores the sentence {c.get('claim')!r} ({c.get('where')}) "
                                        f"that {seen[key]} scores too (counted once)",
                                        "score a sentence in one recipe", damaged=False))
                continue
            seen[key] = r["recipe"]
            out[paper].append(dict(c, recipe=r["recipe"]))
    return out, problems


def scorecard(records: list[dict]) -> dict:
    """Per paper: the sentences scored and how many of each verdict, how many depend on the reading,
    the setup checks (how many hold) and the claims true by construction, the mode and the recipes
    behind them, and the interval decisions with the number expected wrong by chance
    (:func:`pfbench.verdicts.expected_false`)."""
    findings, _ = scored_findings(records)
    out = {}
    for paper in PAPERS:
        recs = [r for r in records if r["recipe"].startswith(paper + ":")]
        counts = {v: 0 for v in VERDICTS}
        for c in findings[paper]:
            counts[c["verdict"]] += 1
        others = [c for r in recs for c in _claims(r) if _kind(c) != FINDING]
        setup = [c for c in others if _kind(c) == SETUP]
        stat = sum(1 for c in findings[paper] if c.get("interval") is not None and c.get("random", True)
                   and c["verdict"] in (AGREE, DISAGREE))
        runs = [int(c["n"]) for c in findings[paper] if isinstance(c.get("n"), int)]
        out[paper] = {"claims": sum(counts.values()), **counts,
                      "depends on reading": sum(1 for c in findings[paper] if c.get("depends_on_reading")),
                      "setup checks": len(setup),
                      "setup checks holding": sum(1 for c in setup if c.get("verdict") == AGREE),
                      "by construction": sum(1 for c in others if _kind(c) == CONSTRUCTION),
                      "interval decisions": stat,
                      "expected wrong by chance": round(expected_false(stat), 2),
                      "recipes": len(recs),
                      "modes": sorted({str(r.get("mode")) for r in recs}),
                      "runs": [min(runs), max(runs)] if runs else None}
    return out


def _fmt(v) -> str:
    """A table cell: numbers shortened, ``|`` escaped and line breaks folded (Markdown tables)."""
    if isinstance(v, float):
        text = f"{v:.4g}"
    elif isinstance(v, (list, tuple)) and len(v) == 2 and all(isinstance(x, (int, float)) for x in v):
        text = f"[{v[0]:.3g}, {v[1]:.3g}]"
    else:
        text = "-" if v is None else str(v)
    return " ".join(text.split()).replace("|", "\\|")


def _verdict_cell(c: dict) -> str:
    text = f"**{c.get('verdict')}**"
    return text + " (depends on reading)" if c.get("depends_on_reading") else text


def _claims_table(claims: list[dict]) -> list[str]:
    """A Markdown table of claims; each claim's other readings follow it as indented rows."""
    lines = ["| claim | where | quantity | ours | 95 % interval | band | paper | verdict | rule |",
             "|---|---|---|---|---|---|---|---|---|"]
    for c in claims:
        rule = c.get("rule")
        if c.get("reading"):
            rule = f"primary reading: {c['reading']}; {rule}"
        if c.get("note"):
            rule = f"{rule}; {c['note']}"
        lines.append(f"| {_fmt(c.get('claim'))} | {_fmt(c.get('where'))} | {_fmt(c.get('quantity'))} | "
                     f"{_fmt(c.get('ours'))} | {_fmt(c.get('interval'))} | {_fmt(c.get('band'))} | "
                     f"{_fmt(c.get('paper'))} | {_verdict_cell(c)} | {_fmt(rule)} |")
        for o in c.get("sensitivity") or []:
            lines.append(f"| ↳ other reading: {_fmt(o.get('reading'))} | | {_fmt(o.get('quantity'))} | "
                         f"{_fmt(o.get('ours'))} | {_fmt(o.get('interval'))} | {_fmt(o.get('band'))} | | "
                         f"{o.get('verdict')} | {_fmt(o.get('rule'))} |")
    return lines + [""]


def _claim_key(recipe: str, c: dict) -> tuple:
    return (recipe, str(c.get("claim")), str(c.get("where")), str(c.get("quantity")))


def _claims_by_key(records: list[dict]) -> dict[tuple, list[dict]]:
    out: dict[tuple, list[dict]] = {}
    for r in records:
        for c in r.get("claims") or []:
            if isinstance(c, dict):
                out.setdefault(_claim_key(r["recipe"], c), []).append(dict(c, mode=r.get("mode")))
    return out


def compare_verdicts(records: list[dict], other_root: str | Path) -> dict:
    """How the verdicts of ``records`` differ from those of the result set under ``other_root``
    (e.g. a paper-scale run against a quick one).

    Claims are matched by (recipe, claim, where, quantity), repeated ones in order. Returns the
    number matched, the claims found in one set only, the count of each verdict transition
    ("undecided -> agree": n) and every changed claim with both verdicts and numbers.
    """
    other_records, _ = check_results(other_root)
    here, there = _claims_by_key(records), _claims_by_key(other_records)
    matched, changed, transitions = 0, [], {}
    for key, cs in here.items():
        olds = there.get(key, [])
        for new, old in zip(cs, olds):
            matched += 1
            if new.get("verdict") != old.get("verdict"):
                t = f"{old.get('verdict')} -> {new.get('verdict')}"
                transitions[t] = transitions.get(t, 0) + 1
                changed.append({"recipe": key[0], "claim": key[1], "where": key[2], "quantity": key[3],
                                "before": old.get("verdict"), "after": new.get("verdict"),
                                "ours_before": old.get("ours"), "ours_after": new.get("ours"),
                                "interval_before": old.get("interval"), "interval_after": new.get("interval"),
                                "mode_before": old.get("mode"), "mode_after": new.get("mode")})
    n_here = sum(len(v) for v in here.values())
    n_there = sum(len(v) for v in there.values())
    return {"other": str(other_root), "matched": matched, "only_here": n_here - matched,
            "only_there": n_there - matched, "transitions": dict(sorted(transitions.items())),
            "changed": changed}


def _comparison_lines(cmp: dict) -> list[str]:
    lines = [f"## Verdicts against `{cmp['other']}`", "",
             f"{cmp['matched']} claims matched, {len(cmp['changed'])} changed verdict; "
             f"{cmp['only_here']} only here, {cmp['only_there']} only there.", ""]
    if cmp["transitions"]:
        lines += ["| change | claims |", "|---|---|"]
        lines += [f"| {t} | {n} |" for t, n in cmp["transitions"].items()]
        lines.append("")
        lines += ["| recipe | claim | quantity | before | after | ours before | ours after |",
                  "|---|---|---|---|---|---|---|"]
        for c in cmp["changed"]:
            lines.append(f"| `{c['recipe']}` | {_fmt(c['claim'])} | {_fmt(c['quantity'])} | {c['before']} | "
                         f"{c['after']} | {_fmt(c['ours_before'])} | {_fmt(c['ours_after'])} |")
        lines.append("")
    return lines


def report_data(out_root: str | Path = "results", compare: str | Path | None = None) -> dict:
    """The report as data (``pfbench report --json``): scorecard, the definitions of the verdict
    words and claim kinds, claims per recipe, problems, and with ``compare`` the verdict changes
    against another result set (:func:`compare_verdicts`)."""
    records, problems = check_results(out_root)
    problems += scored_findings(records)[1]
    extra = {"comparison": compare_verdicts(records, compare)} if compare is not None else {}
    card = scorecard(records)
    total = sum(c["interval decisions"] for c in card.values())
    return {**extra, "scorecard": card,
            "multiplicity": {"interval decisions": total, "expected wrong by chance": round(expected_false(total), 2)},
            "definitions": dict(DEFINITIONS),
            "recipes": {r["recipe"]: {"mode": r.get("mode"), "seed": r.get("seed"),
                                      "damaged": bool(r.get("damaged")), "claims": r.get("claims") or []}
                        for r in records},
            "problems": [{"recipe": p.recipe, "what": p.what, "redo": p.redo, "damaged": p.damaged}
                         for p in problems]}


def _anchor(title: str) -> str:
    """The anchor GitHub-flavoured Markdown gives a heading."""
    keep = "".join(ch for ch in title.lower() if ch.isalnum() or ch in " -_")
    return keep.replace(" ", "-")


def _scorecard_lines(card: dict) -> list[str]:
    lines = ["| paper | mode | recipes | sentences scored | agree | disagree | undecided | not reproducible "
             "| depends on reading | setup checks (holding) | by construction | runs per statistical claim |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    tot = {k: 0 for k in ("recipes", "claims", *VERDICTS, "depends on reading", "setup checks",
                          "setup checks holding", "by construction")}
    for paper, c in card.items():
        for k in tot:
            tot[k] += c[k]
        runs = f"{c['runs'][0]}-{c['runs'][1]}" if c["runs"] else "-"
        lines.append(f"| [{paper}]({paper}/REPORT.md) | {', '.join(c['modes']) or '-'} | {c['recipes']} | "
                     f"{c['claims']} | {c['agree']} | {c['disagree']} | {c['undecided']} | "
                     f"{c['not reproducible']} | {c['depends on reading']} | "
                     f"{c['setup checks']} ({c['setup checks holding']}) | {c['by construction']} | {runs} |")
    lines.append(f"| **all** | | {tot['recipes']} | {tot['claims']} | {tot['agree']} | {tot['disagree']} | "
                 f"{tot['undecided']} | {tot['not reproducible']} | {tot['depends on reading']} | "
                 f"{tot['setup checks']} ({tot['setup checks holding']}) | {tot['by construction']} | |")
    stat = sum(c["interval decisions"] for c in card.values())
    lines += ["", f"{stat} of the agree/disagree verdicts are decisions from a 95 % interval of random "
              f"runs; at most about {expected_false(stat):.1f} of them are expected to be wrong by chance "
              "alone (5 % each), so a lone surprising verdict is not evidence by itself: rerun it with "
              "more runs (`--full`, or `--option runs=...`).", ""]
    return lines


def _recipe_lines(r: dict, paper: str) -> list[str]:
    """One recipe's section of a paper's report: findings, setup checks, claims true by
    construction, the paper-vs-ours table, notes and figures (linked relative to the paper folder)."""
    flag = " (DAMAGED: see the main report)" if r.get("damaged") else ""
    lines = [f"## `{r['recipe']}`: {r.get('title', '')}{flag}", ""]
    load = (r.get("host") or {}).get("load_average")
    busy = (f", load average {load[0]:g}/{load[1]:g}/{load[2]:g} (1/5/15 min) on "
            f"{(r.get('host') or {}).get('cores')} cores" if isinstance(load, list) and len(load) == 3 else "")
    lines += [f"mode {r.get('mode')}, backend {r.get('backend')}, seed {r.get('seed')}, "
              f"{r.get('elapsed_s')} s, git {str(r.get('git_sha'))[:12]}, {r.get('created_utc')}{busy}", ""]
    claims = _claims(r)
    for kind, head in ((FINDING, "Findings (scored)"), (SETUP, "Setup checks (not scored)"),
                       (CONSTRUCTION, "True by construction (not scored)")):
        these = [c for c in claims if _kind(c) == kind]
        if these:
            lines += [f"**{head}**", ""] + _claims_table(these)
    comps = [c for c in r.get("comparisons") or [] if isinstance(c, dict)]
    if comps:
        lines += ["| quantity | ours | paper | deviation | note |", "|---|---|---|---|---|"]
        for c in comps:
            dev = c.get("deviation")
            q = str(c.get("quantity")) + (f" [{c['unit']}]" if c.get("unit") else "")
            ours, pap = c.get("ours"), c.get("paper")
            if ours is None and c.get("ours" + io.NONFINITE_SUFFIX):
                ours = c["ours" + io.NONFINITE_SUFFIX]
            dev = f"{dev:+.1%}" if isinstance(dev, (int, float)) else ""
            lines.append(f"| {_fmt(q)} | {_fmt(ours)} | {_fmt(pap)} | {dev} | {_fmt(c.get('note', ''))} |")
        lines.append("")
    lines += [f"- {n}" for n in r.get("notes") or []]
    outs = [Path(str(o)).name for o in r.get("outputs") or []]
    pngs = [o for o in outs if o.endswith(".png")]
    if pngs:
        lines += [""] + [f"![{r['recipe']}: {o}]({o})" for o in pngs]
    if outs:
        lines += ["", "Outputs: " + ", ".join(f"`{o}`" for o in outs)]
    return lines + [""]


def _paper_report(paper: str, title: str, recs: list[dict], unrun: list[Problem]) -> str:
    lines = [f"# {paper}: {title}", "", "[Back to the scorecard](../REPORT.md)", "", "## Contents", ""]
    lines += [f"- [`{r['recipe']}`: {r.get('title', '')}](#{_anchor(r['recipe'] + ' ' + str(r.get('title', '')))})"
              for r in recs]
    lines += [f"- {p.line()}" for p in unrun] + [""]
    for r in recs:
        lines += _recipe_lines(r, paper)
    return "\n".join(lines) + "\n"


def write_report(out_root: str | Path = "results", compare: str | Path | None = None
                 ) -> tuple[Path, list[Problem]]:
    """Regenerate ``results/REPORT.md`` and ``results/<paper>/REPORT.md`` from every provenance
    record under ``out_root``, each verified against its artefacts (:func:`verify`).

    The main report opens with the scorecard (sentences scored per paper, verdicts, claims that
    depend on the reading, setup checks, claims true by construction, the mode and the number of
    runs; the number of interval decisions expected wrong by chance), then what each verdict word
    and claim kind means, a table of contents, with ``compare`` (another results root, e.g. a quick
    run kept beside a paper-scale one) the verdicts that differ from it, and the "Not reproduced /
    damaged" list. Each paper's report holds its recipes' claims, paper-vs-ours tables, notes and
    figures. Returns the main report's path and the problems.
    """
    out_root = Path(out_root)
    records, problems = check_results(out_root)
    problems = problems + scored_findings(records)[1]
    card = scorecard(records)
    works = "; ".join(f"[{p}]({p}/REPORT.md): {t}" for p, t in PAPERS.items())
    lines = ["# pfbench results report", "",
             "Generated by `pfbench report` from the provenance records under `results/`. Every claim's "
             "verdict is computed from our data by the rule shown beside it (`pfbench.verdicts`). "
             f"Papers: {works}.", "",
             "## Contents", "", "- [Scorecard](#scorecard)", "- [What the words mean](#what-the-words-mean)"]
    if compare is not None:
        lines.append(f"- [Verdicts against `{compare}`](#{_anchor('Verdicts against ' + str(compare))})")
    lines += [f"- [{p}: {t}]({p}/REPORT.md)" for p, t in PAPERS.items()]
    if problems:
        lines.append("- [Not reproduced / damaged](#not-reproduced--damaged)")
    lines += ["", "## Scorecard", ""] + _scorecard_lines(card)
    lines += ["## What the words mean", ""]
    lines += [f"- **{w}**: {DEFINITIONS[w]}" for w in (*VERDICTS, *KINDS)] + [""]
    if compare is not None:
        lines += _comparison_lines(compare_verdicts(records, compare))
    for paper, title in PAPERS.items():
        recs = [r for r in records if r["recipe"].startswith(paper + ":")]
        unrun = [p for p in problems if p.recipe.startswith(paper + ":") and p.what.startswith("not run")]
        if recs or unrun:
            io.make_dirs(out_root / paper)
            io.write_text(out_root / paper / "REPORT.md", _paper_report(paper, title, recs, unrun))
    if problems:
        lines += ["## Not reproduced / damaged", ""] + [f"- {p.line()}" for p in problems] + [""]
    return io.write_text(out_root / "REPORT.md", "\n".join(lines) + "\n"), problems

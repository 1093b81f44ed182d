"""``hyst-gym bench``: speed of every layer, printed and optionally written as JSON / Markdown.

Each layer contributes a section through a module-level ``run_benchmark(report)``
function that prints human-readable lines with ``report(str)`` and returns a dict whose
keys are merged into the top level of the JSON output.

The documentation quotes no hand-typed speed: its speed paragraphs (the site's page
``docs/speed.md``) sit between ``<!-- section:bench-LAYER -->`` and
``<!-- /section:bench-LAYER -->`` markers and are written from one measured run::

    hyst-gym bench --markdown docs/bench.md --page docs/speed.md     # measure, write both

``docs/bench.md`` keeps the machine, the printed lines and the raw figures (a JSON block),
so the speed paragraphs can be rewritten from it without measuring again::

    hyst-gym bench --from docs/bench.md --page docs/speed.md
"""

from __future__ import annotations

import datetime
import importlib
import json
import os
import pathlib
import platform
import re
import sys
import textwrap

import numpy as np

#: (section title, module providing run_benchmark)
SECTIONS = (
    ("hysteresis bank", "hyst_gym.physics.kernel_speed"),
    ("estimators", "hyst_gym.estimation.estimator_speed"),
    ("environments", "hyst_gym.envs.step_speed"),
)
#: layer name (the ``--only`` choice) per module
LAYERS = tuple(module.rsplit(".", 2)[-2] for _, module in SECTIONS)

REGENERATE = "hyst-gym bench --markdown docs/bench.md --page docs/speed.md"
RERENDER = "hyst-gym bench --from docs/bench.md --page docs/speed.md"
_JSON_BLOCK = re.compile(r"<!-- bench-json -->\s*```json\n(.*?)\n```", re.S)


def configure_parser(parser):
    parser.add_argument("--json", metavar="FILE", help="also write the figures as JSON to FILE")
    parser.add_argument("--markdown", metavar="FILE",
                        help="also write the measured tables as Markdown to FILE (the project keeps docs/bench.md)")
    parser.add_argument("--page", "--readme", dest="readme", metavar="FILE",
                        help="rewrite the speed paragraphs of this Markdown page (between its "
                             "<!-- section:bench-LAYER --> markers) from the figures; the project keeps "
                             "them in docs/speed.md (--readme is the old name)")
    parser.add_argument("--from", dest="source", metavar="FILE",
                        help="do not measure: take the figures from an earlier --json or --markdown file")
    parser.add_argument("--only", choices=LAYERS, action="append",
                        help="run only this layer's section (repeatable)")


def machine_info() -> dict:
    """What the figures depend on: platform, cores, load, library versions, date."""
    info = {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
            "cpu_count": os.cpu_count(), "python": platform.python_version(), "numpy": np.__version__,
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")}
    try:
        import numba
        info["numba"] = numba.__version__
    except ImportError:  # pragma: no cover - numba is a dependency
        pass
    if hasattr(os, "getloadavg"):
        info["load_average_start"] = [round(v, 2) for v in os.getloadavg()]
    return info


def measure(only=None) -> dict:
    """Run the benchmark sections (all, or the layers in ``only``); returns the figures."""
    results = {"machine": machine_info(), "layers": [], "lines": {}}
    for (title, module_name), layer in zip(SECTIONS, LAYERS):
        if only and layer not in only:
            continue
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name == module_name:
                print(f"[{title}] not available yet")
                continue
            raise
        print(f"== {title} ==", flush=True)
        lines = results["lines"].setdefault(layer, [])

        def report(line, lines=lines):
            lines.append(line)
            print("  " + line, flush=True)

        results.update(module.run_benchmark(report))
        results["layers"].append(layer)
        if layer == "envs":
            from .envs.config import EnvConfig
            results["env_dt"] = EnvConfig().dt
    if hasattr(os, "getloadavg"):
        results["machine"]["load_average_end"] = [round(v, 2) for v in os.getloadavg()]
    return results


def load(path) -> dict:
    """Figures from an earlier ``--json`` file or ``--markdown`` file."""
    text = pathlib.Path(path).read_text(encoding="utf-8")
    if str(path).endswith(".md"):
        match = _JSON_BLOCK.search(text)
        if match is None:
            raise ValueError(f"{path}: no '<!-- bench-json -->' block with the figures")
        text = match.group(1)
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise ValueError(f"{path}: figures are not valid JSON ({error})") from None


# ---------------------------------------------------------------- rendering

#: line width of the generated Markdown paragraphs (the README's)
WIDTH = 104


def _wrap(text: str) -> str:
    """Wrap each paragraph (a bullet keeps a hanging indent); tables stay one row a line."""
    out = []
    for paragraph in text.split("\n\n"):
        if paragraph.startswith("|"):
            out.append(paragraph)
            continue
        indent = "  " if paragraph.startswith("- ") else ""
        out.append(textwrap.fill(paragraph, WIDTH, subsequent_indent=indent, break_long_words=False,
                                 break_on_hyphens=False))
    return "\n\n".join(out)


def _sci(value, digits=2):
    """``1.2e-6`` rather than Python's ``1.2e-06``."""
    mantissa, exponent = f"{value:.{digits - 1}e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def _us(per_second):
    return 1e6 / per_second


def _machine_words(results) -> str:
    m = results["machine"]
    load = m.get("load_average_start")
    words = f"{m.get('cpu_count', '?')}-core machine, {m.get('date', 'undated')}"
    if load:
        words += f", 1-min load average {load[0]:g} at the start"
    return words


def readme_sections(results, in_readme: bool = True) -> dict:
    """The speed paragraphs of ``docs/speed.md``, one per measured layer (``{layer: markdown}``).

    ``in_readme=False`` words them for ``docs/bench.md`` itself (no link to it). Links are
    relative to a page in ``docs/``."""
    sections = {}
    source = (f"[docs/bench.md](bench.md), one run on a {_machine_words(results)}; other machines differ"
              if in_readme else f"this run, {_machine_words(results)}")
    layers = results.get("layers", [])
    if "physics" in layers:
        r = results
        text = (f"- **Speed** (`hyst-gym bench --only physics`, process CPU time, single thread; figures from "
                f"{source}; regenerate with `{REGENERATE}`): the bank of {r['bank_models']} models sharing one input "
                f"runs at "
                f"**{r['bank_ns_per_model_substep']:.1f} ns per model-substep** (the loop over models is SIMD: "
                f"branch-free, inlined tanh).")
        if r.get("c_reference_ns_per_model_substep"):
            text += (f" In the same run a C `-O3` scalar implementation of the same midpoint step (libm `tanh`) "
                     f"took {r['c_reference_ns_per_model_substep']:.1f} ns.")
        if r.get("solve_ivp_ratio"):
            text += (f" A plain `scipy.integrate.solve_ivp` (RK45, vectorized numpy right-hand side) needs "
                     f"rtol = {_sci(r['solve_ivp_rtol'])} to match the bank's accuracy "
                     f"({_sci(r['solve_ivp_max_error_over_Ms'])} vs {_sci(r['bank_max_error_over_Ms'])} Ms) and is "
                     f"**{r['solve_ivp_ratio']:.0f}x slower**.")
        sections["physics"] = text
    if "estimation" in layers:
        single = results["estimator_steps_per_s"]
        batch = results["estimator_system_steps_per_s_batch64"]
        parts = [f"{_us(single[g]):.1f} µs (G = {g}, {single[g] / 1e3:.0f} k steps/s)" for g in sorted(single, key=int)]
        batched = [f"{64 * _us(batch[g]):.0f} µs (G = {g}, {batch[g] / 1e3:.0f} k system-steps/s)"
                   for g in sorted(batch, key=int)]
        sections["estimation"] = (
            f"**Speed** (`hyst-gym bench --only estimation`, wall time; figures from {source}): one min-max step "
            f"for one system (E = 1; bank + interpolation + two envelope solves + laws, compiled in one numba "
            f"call) takes {' and '.join(parts)}; for E = 64 systems one step takes {' and '.join(batched)}. "
            f"The bank's share of each step is listed in "
            + ("[docs/bench.md](bench.md)." if in_readme else "the printed lines below."))
    if "envs" in layers:
        dt = results.get("env_dt", 0.01)
        single = results["env_single_steps_per_s"]
        vector = results["env_vector_steps_per_s"]
        rows = ["| case | env steps/s | simulated s per wall s | target |", "|---|---|---|---|",
                f"| single env (`gymnasium.make`, wrappers included) | {single:,.0f} | {single * dt:,.0f} | ≥ 5,000 |"]
        for n in sorted(vector, key=int):
            target = "≥ 100,000" if n == "1024" else ""
            rows.append(f"| native vector env, n = {n} | {vector[n]:,.0f} | {vector[n] * dt:,.0f} | {target} |")
        largest = max(vector, key=int)
        sections["envs"] = (
            f"Speed (`hyst-gym bench --only envs`, or `python -m hyst_gym.envs.step_speed`; default Excitation-v0, "
            f"random actions, wall time; figures from {source}):\n\n" + "\n".join(rows) + "\n\n"
            f"One single-env step takes {_us(single):.0f} µs; at n = {largest} one sub-env step takes "
            f"{_us(vector[largest]):.1f} µs.")
    return {layer: _wrap(text) for layer, text in sections.items()}


def markdown(results) -> str:
    """The whole ``docs/bench.md``: machine, the README's paragraphs, printed lines, raw figures."""
    m = results["machine"]
    out = ["# Measured speed (`hyst-gym bench`)", "",
           _wrap(f"Generated by `{m.get('command', REGENERATE)}`; do not edit by hand. The speed "
                 f"paragraphs of [the speed page](speed.md) are written from the figures below (`{RERENDER}` "
                 f"rewrites them without measuring again). Timings depend on the machine and on what else runs "
                 f"on it: rerun the command to get your own."), "",
           "| machine | |", "|---|---|"]
    for key in ("date", "platform", "processor", "cpu_count", "python", "numpy", "numba",
                "load_average_start", "load_average_end"):
        if key in m:
            value = m[key]
            if isinstance(value, list):
                value = ", ".join(f"{v:g}" for v in value) + " (1, 5, 15 min)"
            out.append(f"| {key.replace('_', ' ')} | {value} |")
    titles = dict(zip(LAYERS, (title for title, _ in SECTIONS)))
    sections = readme_sections(results, in_readme=False)
    for layer in results.get("layers", []):
        out += ["", f"## {titles[layer]} (`--only {layer}`)", "", sections[layer], "", "Printed by the run:", "",
                "```text", *results["lines"].get(layer, []), "```"]
    out += ["", "## Raw figures", "", "<!-- bench-json -->", "```json", json.dumps(results, indent=2), "```", ""]
    return "\n".join(out)


def update_readme(path, results) -> list:
    """Replace each measured layer's ``<!-- section:bench-LAYER -->`` block; returns the layers written."""
    path = pathlib.Path(path)
    text = path.read_text(encoding="utf-8")
    written = []
    for layer, body in readme_sections(results).items():
        start, end = f"<!-- section:bench-{layer} -->", f"<!-- /section:bench-{layer} -->"
        if text.count(start) != 1 or text.count(end) != 1 or text.index(start) > text.index(end):
            raise ValueError(f"{path}: expected exactly one {start} ... {end} pair")
        head, rest = text.split(start)
        _, tail = rest.split(end)
        text = f"{head}{start}\n{body.strip()}\n{end}{tail}"
        written.append(layer)
    path.write_text(text, encoding="utf-8")
    return written


def main(args) -> int:
    if args.source:
        results = load(args.source)
        if args.only:
            results["layers"] = [layer for layer in results.get("layers", []) if layer in args.only]
    else:
        results = measure(args.only)
        results["machine"]["command"] = "hyst-gym " + " ".join(sys.argv[1:]) if sys.argv[1:] else "hyst-gym bench"
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
        print(f"wrote {args.json}")
    if args.markdown:
        pathlib.Path(args.markdown).write_text(markdown(results), encoding="utf-8")
        print(f"wrote {args.markdown}")
    if args.readme:
        written = update_readme(args.readme, results)
        print(f"rewrote {args.readme}: speed sections {', '.join(written) or '(none measured)'}")
    return 0

"""``zswarm laws``: the control laws this installation knows, each with its source, its parameters
(published defaults, and with ``--scenario`` their values in that scenario's units) and what it needs."""

from __future__ import annotations

import argparse
import json

from zswarm.args import add_law_arg, add_param_args

DESCRIPTION = ("List the control laws: the built-ins (apf, the paper's; olfati-saber, vasarhelyi, boids) and "
               "those installed packages register (entry-point group zswarm.laws). --law NAME describes one, "
               "a file's (FILE.py:NAME) or a module's (package.module:NAME) too.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="moving-prey",
                        help="fit each law to this scenario and show its parameters there (default moving-prey)")
    add_param_args(parser)
    add_law_arg(parser)
    parser.add_argument("--json", action="store_true", help="print {\"laws\": [...]} as one JSON object")


def run(args: argparse.Namespace) -> int:
    from zswarm.laws.registry import bind, describe, known
    from zswarm.paper.params import parse_assignments
    from zswarm.swarm.scenarios import get_scenario

    sets = parse_assignments(args.assignments)
    names = [sets["law"]] if "law" in sets else known()
    rows = []
    for name in names:
        entry = describe(name)
        scenario = get_scenario(args.scenario, {**sets, "law": name} if "law" in sets else {"law": name})
        fitted = bind(scenario).describe()
        entry["fitted"] = {"scenario": scenario.name, **{k: fitted[k] for k in ("units", "scaled") if k in fitted}}
        rows.append(entry)
    if args.json:
        print(json.dumps({"laws": rows}, sort_keys=True, default=str))
        return 0
    for e in rows:
        print(f"{e['name']}  ({e['source']}; {'batched' if e['batched'] else 'per agent'}"
              f"{'; tunable' if e['tunable'] else ''}{'; design guidelines' if e['guidelines'] else ''})")
        print(f"    {e['reference']}")
        if e["needs"]:
            print(f"    needs: {', '.join(e['needs'])}")
        if isinstance(e["params"], str):
            print(f"    parameters: {e['params']}")
            continue
        units, scaled = e["fitted"].get("units"), e["fitted"].get("scaled", {})
        if units:
            print(f"    in {e['fitted']['scenario']}: 1 law length = {units['length']:.4g}, 1 law speed = "
                  f"{units['speed']:.4g}, 1 law second = {units['time']:.4g} s")
        for p in e["params"]:
            here = f" (here {scaled[p['name']]:.4g})" if p["name"] in scaled and p["dimension"] != "none" else ""
            print(f"    law.{p['name']:<12} {p['default']:<8g}{here:<18} {p['doc']}")
    return 0

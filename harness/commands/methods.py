"""`harness methods [--json]`: the registered pruners, what they need and their parameters."""

from __future__ import annotations

import json

NAME = "methods"
HELP = "list the registered pruners (name, needs, parameters, summary)"


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON list")


def run(args) -> int:
    from methods import list_pruners

    specs = list_pruners()
    rows = [
        {"name": s.name, "needs": sorted(s.needs), "params": dict(s.params), "summary": s.summary}
        for s in specs
    ]
    if args.json:
        print(json.dumps(rows, indent=2, default=str))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(title="registered pruners")
    for col in ("name", "needs", "parameters", "summary"):
        table.add_column(col, overflow="fold")
    for r in rows:
        params = ", ".join(f"{k}={v!r}" for k, v in r["params"].items()) or "-"
        table.add_row(r["name"], ", ".join(r["needs"]) or "-", params, r["summary"])
    Console(width=160).print(table)
    return 0

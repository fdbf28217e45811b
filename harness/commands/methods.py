"""`harness methods [--json] [--docs]`: the registered pruners, what they need and their typed parameters
(a reading parameter of the paper also shows its documentation; `--json` adds the sentence it reads)."""

from __future__ import annotations

NAME = "methods"
HELP = "list the registered pruners (name, label, group, needs, parameters with types and ranges)"


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON list (with each parameter's doc and "
                        "the paper sentence a reading parameter reads)")
    parser.add_argument("--docs", action="store_true", help="show every parameter's documentation in the table "
                        "(reading parameters always show theirs)")


def run(args) -> int:
    from harness.api.scenes import methods

    rows = methods()
    if args.json:
        from harness.core.jsonout import dumps

        print(dumps(rows, indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    table = Table(title="registered pruners")
    for col in ("name", "group", "needs", "parameters", "summary"):
        table.add_column(col, overflow="fold")
    for r in rows:
        params = (
            "\n".join(
                f"{k} = {v['default']!r}  ({v['type']})"
                + (f"\n  [dim]{v['doc']}[/]" if args.docs or "reading" in v else "")
                for k, v in r["params"].items()
            )
            or "-"
        )
        table.add_row(f"{r['name']}\n[dim]{r['label']}[/]", r["group"], ", ".join(r["needs"]) or "-", params,
                      r["summary"])
    Console(width=160).print(table)
    return 0

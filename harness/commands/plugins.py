"""`harness plugins [--json]`: every installed plugin, whether it loaded, what it registered, or why not.

Each entry-point group's registry is asked for its whole list, so its built-ins load first and every
installed plugin of the group is visited as a guest (:mod:`harness.core.plugins`): the ones that
loaded with the names they registered, the ones skipped with the reason (an import error, a
``sys.exit``, a wrong field, a name a built-in holds). ``HARNESS_PLUGINS`` narrows what is visited.
"""

from __future__ import annotations

NAME = "plugins"
HELP = "list the installed plugins (pruners, metrics, formats, tables, plots, renderers, protocols): loaded or why not"

#: the registry each entry-point group fills (``module:attribute``)
REGISTRIES = {"harness.pruners": "methods.registry:PRUNERS", "harness.metrics": "harness.metrics.registry:METRICS",
              "harness.formats": "harness.io.formats:FORMATS", "harness.tables": "harness.report.tables:TABLE_SPECS",
              "harness.plots": "harness.report.plots:PLOT_SPECS", "harness.renderers": "renderers:RENDERERS",
              "harness.protocols": "harness.views.protocols:PROTOCOL_SPECS"}


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON list: group, entry point, module, "
                        "distribution, version, status (loaded or skipped), reason, registered names")


def visit_every_group() -> list:
    """Load every group's built-ins and plugins; the visits, in group order."""
    import importlib

    from harness.core import plugins

    for group, where in REGISTRIES.items():
        module, _, attr = where.partition(":")
        getattr(importlib.import_module(module), attr).names()
    order = list(REGISTRIES)
    return sorted(plugins.records(), key=lambda v: order.index(v.group) if v.group in order else len(order))


def run(args) -> int:
    import os

    from harness.core import plugins

    visits = visit_every_group()
    if args.json:
        from harness.core.jsonout import dumps

        print(dumps([v.as_dict() for v in visits], indent=2))
        return 0
    chosen = os.environ.get(plugins.ENV)
    print(f"plugins ({plugins.ENV}={chosen})" if chosen is not None else
          f"plugins (every installed distribution; {plugins.ENV}=a,b or none narrows them)")
    for group, what in plugins.GROUPS.items():
        mine = [v for v in visits if v.group == group]
        print(f"{group} ({what}): " + ("none installed" if not mine else f"{len(mine)}"))
        for v in mine:
            detail = ", ".join(v.registered) or "(registered nothing)" if v.status == "loaded" else v.reason
            print(f"  {v.status:8s} {v.distribution} {v.version}  {v.name} = {v.value}  {detail}")
    return 0

"""MkDocs hooks of spco's documentation site (``hooks:`` in mkdocs.yml).

The command-line reference (docs/reference/cli.md) is rendered by mkdocs-click, whose table style
prints ``option.default`` as it is. Since click 8.3 an option without a default holds click's
``UNSET`` sentinel there, so the page showed "Sentinel.UNSET" as the default of every such option.
:func:`on_startup` makes mkdocs-click read the default the way click describes its own parameters
(:meth:`click.Parameter.to_info_dict`, which gives ``None`` for no default), as the pending upstream
fix does (mkdocs/mkdocs-click pull request 95); remove it once a mkdocs-click release carries that.
"""

from __future__ import annotations

from typing import Any

import click


def _default_of(option: click.Option) -> Any:
    """The option's default as click documents it: ``None`` when it has none."""
    return option.to_info_dict().get("default")


def _table_row(option: click.Option) -> str:
    """One row of mkdocs-click's option table, with the option's real default."""
    from mkdocs_click import _docs

    names = ", ".join(f"`{opt}`" for opt in option.opts)
    if option.secondary_opts:
        names += " / " + ", ".join(f"`{opt}`" for opt in option.secondary_opts)
    value_type = _docs._format_table_option_type(option)
    description = option.help if option.help is not None else "N/A"
    default = _default_of(option)
    if default is None:
        shown = "_required" if option.required else "None"
    else:
        shown = f"`{default}`"
    return f"| {names} | {value_type} | {description} | {shown} |"


def on_startup(**_: Any) -> None:
    """Before the build: mkdocs-click's table rows through :func:`_table_row`."""
    from mkdocs_click import _docs

    _docs._format_table_option_row = _table_row

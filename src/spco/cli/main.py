"""The ``spco`` command line: the click group :func:`main` and the registration of the commands,
which live one module per group beside it (:mod:`spco.cli.data`, :mod:`~spco.cli.demo`,
:mod:`~spco.cli.knowledge`, :mod:`~spco.cli.experiment`, :mod:`~spco.cli.features`,
:mod:`~spco.cli.bench`, :mod:`~spco.cli.bag`, :mod:`~spco.cli.ask`, :mod:`~spco.cli.active`,
:mod:`~spco.cli.serve`, :mod:`~spco.cli.ros`; errors: :mod:`spco.cli.errors`).

Every command validates its input at the boundary; an :class:`~spco.errors.SpcoError` (bad file,
bad argument) is printed as one line ``error: ...`` and the command exits with status 2, without a
traceback.
"""

from __future__ import annotations

import click

from spco import __version__


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="spco")
def main() -> None:
    """spco: spatial concepts for home robots, learnt across homes and transferred to new ones.

    Start with `spco demo` (synthetic homes, no dataset needed), or point `spco inspect` at a
    folder of homes (the authors' SIGVerse layout or spco's plain format).
    """


def _register_commands() -> None:
    """Add the command groups that live in their own modules."""
    from spco.cli.active import active
    from spco.cli.ask import ask
    from spco.cli.bag import import_bag
    from spco.cli.bench import bench
    from spco.cli.data import DATA_COMMANDS
    from spco.cli.demo import demo
    from spco.cli.experiment import experiment
    from spco.cli.features import features
    from spco.cli.knowledge import KNOWLEDGE_COMMANDS
    from spco.cli.ros import ros, ros2
    from spco.cli.serve import serve
    from spco.cli.show import show

    for command in DATA_COMMANDS:  # inspect, import, synth
        main.add_command(command)
    main.add_command(demo)
    experiment.add_command(active)  # spco experiment active
    main.add_command(experiment)
    main.add_command(features)
    main.add_command(bench)
    main.add_command(import_bag)
    main.add_command(ros)
    main.add_command(ros2)
    for command in KNOWLEDGE_COMMANDS:  # fit, adapt, where, what, teach
        main.add_command(command)
    main.add_command(show)
    main.add_command(ask)
    main.add_command(serve)


_register_commands()


if __name__ == "__main__":  # pragma: no cover
    main()

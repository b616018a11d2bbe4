"""``spco ask HOME [--n K] [--json]``: where in the home an answer to "what is this place?" teaches
the most (:func:`spco.knowledge.ask`).

Registered in :mod:`spco.cli.main`.
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from spco.cli.errors import friendly_errors

__all__ = ["ask", "confidence_note"]


def confidence_note(question: dict) -> str:
    """How a question's confidence follows from the answer line's numbers (``spco ask``): the best
    name's p times the chance that the room has no name of its own, when that is what it is; else
    that the room's taught names count too."""
    names, rho = question.get("names") or [], float(question.get("own_name", 0.0))
    if not names:
        return ""
    best = float(names[0]["p"])
    if abs(best * (1.0 - rho) - float(question["confidence"])) <= 5e-3:
        return (f" = {names[0]['name']} {best:.2f} × {1.0 - rho:.2f}, the chance that the room has no "
                f"name of its own" if rho > 0 else "")
    return " (the names taught in this room counted)"


@click.command(name="ask")
@click.argument("home_file", metavar="HOME", type=click.Path(path_type=Path))
@click.option("--n", "-n", "n", default=5, show_default=True, type=click.IntRange(1, 1000),
              help="How many questions.")
@click.option("--json", "as_json", is_flag=True,
              help='Print a JSON object {"questions": [{"id", "x", "y", "theta", "gain", "reason", …}]}.')
@click.option("--unsure-only", is_flag=True,
              help="Only the questions worth asking: where the robot's confidence in the answer it "
                   "expects is below 0.7, spco.model.confidence.UNSURE_BELOW (none listed: nothing is "
                   "worth asking).")
@friendly_errors
def ask(home_file: Path, n: int, as_json: bool, unsure_only: bool) -> None:
    """Where to ask "what is this place?" in the home of HOME, best first.

    Each of the home's recorded samples without a name taught is scored by the expected number of
    its room's answers that an answer there corrects (the gain): high where concepts compete, where
    a room looks like nothing the experienced homes had, and where a room may have a name of its
    own. One question per room comes first. Record the answer with
    `spco teach HOME --id ID --sentence "…"`.
    """
    from spco.cli.common import load_home
    from spco.service.answers import ask_answer

    home = load_home(home_file)
    answer = ask_answer(home, n, unsure_only=unsure_only)
    if as_json:
        click.echo(json.dumps(answer, indent=1))
        return
    questions = answer["questions"]
    if not questions:
        click.echo(f"Nothing worth asking in home {home.name}: the robot is sure of every answer it "
                   "expects." if unsure_only else f"Every recorded sample of home {home.name} has a name "
                   "taught: nothing left to ask.")
        return
    click.echo(f"Where to ask in home {home.name}, best first (gain: {answer['gain']}):")
    for rank, q in enumerate(questions, 1):
        said = ", ".join(f"{p['name']} {p['p']:.2f}" for p in q["names"]) or "no name yet"
        click.echo(f"{rank:3d}. sample {q['id']} at x={q['x']:.2f} y={q['y']:.2f} θ={q['theta']:.2f}  "
                   f"gain {q['gain']:.1f}")
        click.echo(f"     {q['reason']}")
        sure = "" if q["worth_asking"] else "; it is sure of the answer: not worth asking"
        click.echo(f"     the robot would say: {said} (`what` here); confidence {q['confidence']:.2f}"
                   f"{confidence_note(q)}{sure}")
    first = questions[0]
    click.echo(f'Record an answer: spco teach {home_file} --id {first["id"]} --sentence "this is …"')

"""The main job on the embedded default: learn from synthetic homes, transfer to a new one.

``spco demo`` generates experienced homes (every sample taught) and one new home (nothing
taught), learns the transfer model (with mutual-information word pruning) from all of them at
once, then, in the new home, predicts the place name of every test observation from its position
and view, and positions for every place name. It prints A_n and A_p per place beside chance and
beside the SpCoA+MI baseline (which learns the new home alone and so cannot name anything), and
writes a map of the new home with the learnt regions and the predicted positions.

Then it does what a robot does (the paper's protocol above learns the new home jointly with the
others): it learns knowledge from the experienced homes alone (``fit_knowledge``), adapts it to the
new home (``adapt``, nothing taught) and writes ``knowledge.spco`` and ``home.spco``, which
``spco where`` / ``what`` / ``teach`` / ``serve`` / ``ros`` take as they are.

With ``processes=2`` (``spco demo`` on a machine of 2 cores or more) the robot's files are made in
a second process at the same time as the transfer fit, the baseline and the figures, and on a
cold cache the two processes first compile the kernels between them, each taking the next kernel
not yet taken (:func:`~spco.model.precompile.compile_in_turn`), and load the other's from the
cache. Each part depends on the seed alone, so the results and files are the same as with one
process.
"""

from __future__ import annotations

import contextlib
import json
import pickle
import time
import traceback
from collections.abc import Iterator
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from spco.data.environment import Corpus
from spco.data.synthetic import generate_homes
from spco.errors import SpcoError
from spco.evaluation.metrics import HomeScores, evaluate_home
from spco.model.precompile import compile_in_turn, load_kernels
from spco.model.transfer import SpCoA, SpCoTransfer


@dataclass
class DemoResult:
    """What :func:`run_demo` measured and wrote."""

    transfer: HomeScores
    baseline: HomeScores
    fit_seconds: float
    n_homes: int
    n_samples: int
    files: list[Path]
    warm_up_seconds: float = 0.0
    home_file: Path | None = None
    knowledge_file: Path | None = None
    robot_seconds: float = 0.0


def run_demo(seed: int = 0, out: Path | str = "spco-demo", n_experienced: int = 16,
             n_iterations: int = 100, progress: bool = True, processes: int = 1,
             compile_first: bool = False) -> DemoResult:
    """Run the demo and write its figures and ``results.json`` into ``out``.

    The kernels are loaded from Numba's cache (or compiled) first
    (:func:`~spco.model.precompile.load_kernels`), so that ``fit_seconds`` times the learning
    alone: ``warm_up_seconds``.

    ``processes=2`` makes the robot's files (:func:`_robot_files`) in a second (spawned) process
    while this one fits, evaluates and draws; with ``compile_first`` (a cold cache) the two
    processes first compile the kernels between them, taking turns. The same results as one
    process; a script calling it with 2 needs the ``if __name__ == "__main__":`` guard of
    :mod:`multiprocessing`.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if processes <= 1:
        warm_up_seconds = load_kernels()
        corpus, new_index = _demo_homes(seed, n_experienced)
        result = _learn_and_draw(corpus, new_index, out, seed, n_experienced, n_iterations, progress)
        start = time.perf_counter()
        knowledge_file, home_file = _robot_files(corpus, new_index, out, seed, n_iterations, progress)
        robot_seconds = time.perf_counter() - start
    else:
        with _RobotProcess(seed, out, n_experienced, n_iterations, compile_first) as robot, _one_thread():
            start = time.perf_counter()
            if compile_first:  # (warm: no waiting for the other process to start)
                corpus, new_index = _demo_homes(seed, n_experienced)
                _look_up_words(corpus, new_index)
                # matplotlib too (what _learn_and_draw imports, ~0.3 s of CPU), before the turns
                # that balance it: after them the other process waits for nothing of this
                import spco.plots  # noqa: F401
                compile_in_turn(robot.turns)
                robot.wait_for_its_kernels()
            load_kernels()
            warm_up_seconds = time.perf_counter() - start
            if not compile_first:
                corpus, new_index = _demo_homes(seed, n_experienced)
            result = _learn_and_draw(corpus, new_index, out, seed, n_experienced, n_iterations, progress)
            knowledge_file, home_file, robot_seconds = robot.result()
    result.files += [knowledge_file, home_file]
    result.warm_up_seconds = warm_up_seconds
    result.home_file, result.knowledge_file, result.robot_seconds = home_file, knowledge_file, robot_seconds
    return result


def _look_up_words(corpus: Corpus, new_index: int) -> None:
    """Ask WordNet, once, what both processes' fits ask of the homes' words, so that the lexicon's
    cache files hold it before either fit starts: the word channels' evidence
    (:func:`~spco.model.name_evidence.channel_evidence`: word and kind facts) and the names the
    objects stand in for (:func:`~spco.model.unheard.stand_in_columns`: the transfer fit's of all
    the homes, the robot's knowledge fit's of the experienced homes). On a first run the other
    process compiles meanwhile, and then reads the answers from the files instead of loading NLTK
    and WordNet itself (later runs read the files in both processes anyway)."""
    from spco.model.hyperparameters import TransferHyperparameters
    from spco.model.name_evidence import channel_evidence
    from spco.model.unheard import stand_in_columns
    from spco.model.word_channels import WordChannels

    channel_evidence(corpus.vocabulary, [])
    weight = TransferHyperparameters().evidence_weight
    for homes in (corpus, _experienced(corpus, new_index)):
        sentences = [s for t in homes.training_set() for s in t.sentences]
        evidence, content = channel_evidence(homes.vocabulary, sentences)
        stand_in_columns(homes.vocabulary, WordChannels.initial(evidence, 1, weight, content).name_prior())


@contextlib.contextmanager
def _one_thread() -> Iterator[None]:
    """Numba's thread count 1 while inside (then as before): with two processes on two cores, a
    kernel's parts on a second thread only wait for a core the other process holds. The draws do
    not depend on the parts (:func:`~spco.model.kernels.dispatch._call_in_parts`)."""
    import numba

    previous = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def _portable(error: BaseException) -> BaseException | str:
    """``error`` as the parent process can unpickle it: itself; or, for an error of spco's whose
    arguments do not round-trip, a :class:`~spco.errors.SpcoError` with its message (the command
    line prints it as one line); or else its traceback's text."""
    try:
        pickle.loads(pickle.dumps(error))
        return error
    except Exception:
        if isinstance(error, SpcoError):
            return SpcoError(str(error))
        return "".join(traceback.format_exception(error))


def _demo_homes(seed: int, n_experienced: int) -> tuple[Corpus, int]:
    """The demo's synthetic homes (the experienced ones, then the new one) and the new one's index."""
    corpus = generate_homes(n_experienced + 1, seed=seed, new_homes=1, specific_rooms=False)
    return corpus, len(corpus) - 1


def _learn_and_draw(corpus: Corpus, new_index: int, out: Path, seed: int, n_experienced: int,
                    n_iterations: int, progress: bool) -> DemoResult:
    """The paper's protocol on the demo's homes: the transfer fit and the SpCoA+MI baseline scored
    in the new home, its map, the log-joint trace and ``results.json`` (the robot's files not yet)."""
    new_home = corpus[new_index]
    rng = np.random.default_rng(seed)
    start = time.perf_counter()
    model = SpCoTransfer(prune_words=True, n_iterations=n_iterations, random_state=seed,
                         progress=progress).fit(corpus)
    fit_seconds = time.perf_counter() - start
    transfer = evaluate_home(model.parameters_, new_index, new_home, corpus.vocabulary, rng=rng)
    baseline_model = SpCoA(prune_words=True, n_iterations=n_iterations, random_state=seed,
                           progress=progress).fit(corpus, home=new_home.name)
    baseline = evaluate_home(baseline_model.parameters_, 0, new_home, corpus.vocabulary, rng=rng)

    from spco import plots

    map_path = out / "new_home_map.png"
    positions, _ = new_home.test_observations()
    shown = np.linspace(0, positions.shape[0] - 1, num=min(6, positions.shape[0])).astype(int)
    top = transfer.name_predictions
    plots.plot_home_map(
        model.parameters_, new_index, new_home, corpus.vocabulary,
        predicted_positions=transfer.predicted_positions,
        poses=positions[shown],
        pose_names=[list(zip(top.words[i], top.probabilities[i], strict=True)) for i in shown],
        title=f"{new_home.name}: learnt regions and predicted positions (nothing taught here)",
        path=map_path)
    trace_path = out / "log_joint.png"
    plots.plot_log_joint(model.log_joint_, path=trace_path)
    results_path = out / "results.json"
    results_path.write_text(json.dumps({
        "seed": seed, "experienced_homes": n_experienced, "iterations": n_iterations,
        "fit_seconds": fit_seconds, "new_home": new_home.name,
        "transfer": transfer.summary(), "spcoa_mi": baseline.summary(),
    }, indent=1, default=_json_default), encoding="utf-8")
    return DemoResult(transfer=transfer, baseline=baseline, fit_seconds=fit_seconds, n_homes=len(corpus),
                      n_samples=sum(e.n_samples for e in corpus), files=[map_path, trace_path, results_path])


class _RobotProcess:
    """The demo's second process: on a cold cache it compiles kernels in turn with this process
    (:func:`~spco.model.precompile.compile_in_turn` on the shared counter :attr:`turns`) and waits
    for this process's last one (:meth:`wait_for_its_kernels`); then it makes the robot's files
    (:func:`_robot_worker`). A context manager: leaving it early ends the process."""

    def __init__(self, seed: int, out: Path, n_experienced: int, n_iterations: int, compile_first: bool):
        context = get_context("spawn")
        self._ours, self._theirs = context.Event(), context.Event()
        self._receiver, sender = context.Pipe(duplex=False)
        #: the next cluster of kernels to compile, shared by both processes on a cold cache
        self.turns = context.Value("i", 0)
        self._process = context.Process(
            target=_robot_worker, name="spco-demo-robot", daemon=True,
            args=(sender, self._theirs, self._ours, self.turns, seed, out, n_experienced, n_iterations,
                  compile_first))
        self._process.start()
        sender.close()

    def __enter__(self) -> _RobotProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self._ours.set()
        if self._process.is_alive() and exc[0] is not None:
            self._process.terminate()
        self._process.join()

    def wait_for_its_kernels(self) -> None:
        """Say that this process's kernels are in the cache, and wait for the other's."""
        self._ours.set()
        while not self._theirs.wait(0.2):
            if not self._process.is_alive():
                self._raise_its_error()

    def result(self) -> tuple[Path, Path, float]:
        """The knowledge file, the home file and the seconds the second process took to make them."""
        while not self._receiver.poll(0.2):
            if not self._process.is_alive() and not self._receiver.poll(0):
                self._raise_its_error()
        status, payload = self._receiver.recv()
        if status == "error":
            raise payload if isinstance(payload, BaseException) else RuntimeError(payload)
        return payload

    def _raise_its_error(self) -> None:
        if self._receiver.poll(0):
            status, payload = self._receiver.recv()
            if status == "error":
                raise payload if isinstance(payload, BaseException) else RuntimeError(payload)
        raise RuntimeError(f"the demo's second process ended early (exit code {self._process.exitcode})")


def _robot_worker(sender, compiled_here, compiled_there, turns, seed: int, out: Path, n_experienced: int,
                  n_iterations: int, compile_first: bool) -> None:
    """The second process of :func:`run_demo` (see :class:`_RobotProcess`): sends ``("ok",
    (knowledge file, home file, seconds))`` or ``("error", exception)``."""
    try:
        import numba

        numba.set_num_threads(1)  # (see _one_thread)
        if compile_first:
            compile_in_turn(turns)
            compiled_here.set()
            compiled_there.wait()
        load_kernels()
        corpus, new_index = _demo_homes(seed, n_experienced)
        start = time.perf_counter()
        files = _robot_files(corpus, new_index, out, seed, n_iterations, progress=False)
        sender.send(("ok", (*files, time.perf_counter() - start)))
    except BaseException as error:  # the parent raises it
        sender.send(("error", _portable(error)))
    finally:
        sender.close()


def _robot_files(corpus: Corpus, new_index: int, out: Path, seed: int, n_iterations: int,
                 progress: bool) -> tuple[Path, Path]:
    """Knowledge of the experienced homes alone, adapted to the new home (nothing taught): the two
    files a robot uses, ``out/knowledge.spco`` and ``out/home.spco`` (replaced if there)."""
    from spco.knowledge import adapt, fit_knowledge

    knowledge = fit_knowledge(_experienced(corpus, new_index), n_iterations=n_iterations,
                              random_state=seed, progress=progress,
                              provenance={"data": "spco demo (synthetic homes)", "seed": seed})
    knowledge_file = knowledge.save(out / "knowledge.spco", overwrite=True)
    home = adapt(knowledge, corpus[new_index], n_iterations=n_iterations, random_state=seed,
                 progress=progress)
    home_file = home.save(out / "home.spco", overwrite=True)
    return Path(knowledge_file), Path(home_file)


def _experienced(corpus: Corpus, new_index: int) -> Corpus:
    """The homes the robot's knowledge is learnt from: all but the new one."""
    return Corpus([home for i, home in enumerate(corpus) if i != new_index])


def _json_default(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def format_table(result: DemoResult) -> str:
    """The per-place table printed by ``spco demo``."""
    t, b = result.transfer, result.baseline
    lines = [f"{'place':<14}{'A_n':>7}{'A_p':>7}   {'SpCoA+MI A_n':>13}{'A_p':>7}"]
    for place in t.places:
        lines.append(f"{place:<14}{_fmt(t.name_accuracy.get(place))}{_fmt(t.position_accuracy.get(place))}   "
                     f"{_fmt(b.name_accuracy.get(place), 13)}{_fmt(b.position_accuracy.get(place))}")
    lines.append(f"{'mean':<14}{_fmt(t.mean_name_accuracy)}{_fmt(t.mean_position_accuracy)}   "
                 f"{_fmt(b.mean_name_accuracy, 13)}{_fmt(b.mean_position_accuracy)}")
    lines.append(f"{'chance':<14}{_fmt(t.name_chance)}{_fmt(t.position_chance)}")
    return "\n".join(lines)


def _fmt(value: float | None, width: int = 7) -> str:
    if value is None or not np.isfinite(value):
        return f"{'-':>{width}}"
    return f"{value:>{width}.2f}"

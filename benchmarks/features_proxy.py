"""Quick proxy for choosing the default image extractor: place-label accuracy across homes.

For every candidate descriptor, the images of the paper's 16 experienced SIGVerse homes are the
training set (labels from ``name_label``) and the test samples of the new homes (1LDK_9, 2LDK_9,
3LDK_9) the test set. Two scores: 1-nearest-neighbour (cosine of L1-normalised counts) and a
multinomial naive-Bayes classifier on the counts (closer to the model's visual likelihood). The
authors' fc7 features are scored the same way as the reference. Also reports images/s of each
extractor (one process). Run: ``python benchmarks/features_proxy.py`` (about a minute per candidate).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from data_paths import DATASETS

from spco.data.sigverse import read_sigverse_home
from spco.features import ExtractorSpec, build_extractor, read_image

DATA = DATASETS
EXPERIENCED = ["3LDK_1", "1LDK_8", "2LDK_8", "1LDK_7", "2LDK_7", "1LDK_6", "2LDK_6", "1LDK_5",
               "2LDK_5", "1LDK_4", "2LDK_4", "1LDK_3", "2LDK_3", "1LDK_2", "2LDK_2", "1LDK_1"]
NEW = ["1LDK_9", "2LDK_9", "3LDK_9"]


def labels_of(home: str, n: int) -> list[str]:
    folder = DATA / "sigverse" / home / "name_label"
    return [(folder / f"word{i}.txt").read_text().strip() if (folder / f"word{i}.txt").exists() else ""
            for i in range(n)]


def scores(train: np.ndarray, y_train: np.ndarray, test: np.ndarray,
           y_test: np.ndarray) -> tuple[float, float]:
    def unit(a: np.ndarray) -> np.ndarray:
        a = a / np.maximum(a.sum(1, keepdims=True), 1e-12)
        return a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-12)
    nn = (unit(test) @ unit(train).T).argmax(1)
    acc_nn = float((y_train[nn] == y_test).mean())
    classes = np.unique(y_train)
    log_phi = np.log(np.stack([train[y_train == c].sum(0) + 1.0 for c in classes]))
    log_phi -= np.log(np.exp(log_phi).sum(1, keepdims=True))
    pred = classes[(test @ log_phi.T).argmax(1)]
    return acc_nn, float((pred == y_test).mean())


def main(names: list[str]) -> None:
    homes = {}
    for home in EXPERIENCED + NEW:
        env, _ = read_sigverse_home(DATA / "sigverse" / home)
        homes[home] = env
    label = {h: np.array(labels_of(h, homes[h].n_samples)) for h in homes}
    train_rows = [(h, i) for h in EXPERIENCED for i in np.flatnonzero(~homes[h].is_test) if label[h][i]]
    test_rows = [(h, i) for h in NEW for i in np.flatnonzero(homes[h].is_test) if label[h][i]]
    y_train = np.array([label[h][i] for h, i in train_rows])
    y_test = np.array([label[h][i] for h, i in test_rows])

    def fc7(rows: list[tuple[str, int]]) -> np.ndarray:
        return np.vstack([homes[h].visual[[i]].toarray() for h, i in rows]).astype(float)

    if "fc7" in names:
        print(f"fc7 (authors'): NN {scores(fc7(train_rows), y_train, fc7(test_rows), y_test)}", flush=True)
    images = {h: [read_image(DATA / "sigverse_images" / h / f"{i}.jpg") for i in range(homes[h].n_samples)]
              for h in homes}
    for name in names:
        if name == "fc7":
            continue
        spec_name, _, opts = name.partition(":")
        settings = dict(kv.split("=") for kv in opts.split(",") if kv)
        settings = {k: (float(v) if "." in v else int(v)) for k, v in settings.items()}
        extractor = build_extractor(ExtractorSpec(spec_name, settings=settings))
        if extractor.needs_fit:
            extractor = extractor.fitted([images[h][i] for h, i in train_rows[::5]], random_state=0)
        start = time.perf_counter()
        x_train = extractor.extract_many([images[h][i] for h, i in train_rows]).toarray().astype(float)
        seconds = time.perf_counter() - start
        x_test = extractor.extract_many([images[h][i] for h, i in test_rows]).toarray().astype(float)
        rate = len(train_rows) / seconds
        print(f"{name}: dim {x_train.shape[1]}, counts/image {x_train.sum(1).mean():.0f}, "
              f"{rate:.0f} images/s (decoded), (NN, NB) accuracy {scores(x_train, y_train, x_test, y_test)}",
              flush=True)


if __name__ == "__main__":
    main(sys.argv[1:] or ["fc7", "colour-hog"])

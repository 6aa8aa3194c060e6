"""The reaction classifier (dynamic response, sections 4.1 and 4.2): an SVM picks the reaction clip from
the simulated state just after contact.

scikit-learn's ``SVC`` with a polynomial kernel ``K(x, y) = (gamma x.y + coef0)^degree`` on standardized
features (:mod:`kinodyn.response.features`), the cost ``C``, ``degree`` and ``coef0`` chosen by
cross-validation over a small grid. Class probabilities are Platt-scaled the way scikit-learn recommends
since ``SVC(probability=True)`` was deprecated: ``CalibratedClassifierCV(SVC(...), method="sigmoid",
ensemble=False)`` (one SVC fitted on all cases, its decision values calibrated on cross-validated
predictions); the predicted clip is the most probable one. The accuracy stored with a model is that of
this calibrated classifier, cross-validated. A model is saved as a folder: ``model.skops`` (the fitted
scaler and classifier through skops, never pickle; only the scikit-learn and numpy types this module uses
are trusted on loading) and ``model.json`` (feature set, clip names, the library signature it was trained
for, cross-validation scores, training size). Loading checks the library.

Needs the optional ``learn`` extra (scikit-learn, skops).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinodyn.errors import FileFormatError, ParameterError
from kinodyn.io.atomic import atomic_path
from kinodyn.response.features import FEATURE_SETS, features

__all__ = ["GRID", "MIN_CASES", "NEAR_OPTIMUM", "ReactionModel", "train"]

FORMAT = "kinodyn.response-model/1"
#: Cross-validation grid of the SVC (the kernel is polynomial throughout).
GRID = {"svc__C": [1.0, 3.0, 10.0, 30.0], "svc__degree": [2, 3], "svc__coef0": [1.0]}
#: The secondary measure stored with a model: cross-validated choices whose clip's own best error D is
#: within this factor of the exhaustive optimum (labels are often near-ties).
NEAR_OPTIMUM = 1.10
#: Folds of the calibration of the chosen SVC's decision values.
CALIBRATION_FOLDS = 3
#: Fewest cases of a clip label for the classifier to learn it (each calibration fold of each
#: cross-validation fold needs some); cases of rarer labels are left out of fitting but still count,
#: as misses, in the cross-validated accuracy.
MIN_CASES = 6
_TRUSTED_PREFIXES = ("sklearn.", "numpy.")


@dataclass
class ReactionModel:
    """A trained classifier.

    Attributes:
        pipeline: the fitted scikit-learn pipeline (StandardScaler then the calibrated SVC).
        kind: feature set, ``"large"`` or ``"small"``.
        clips: names of the library's clips (class ``k`` is clip ``clips[k]``).
        library: signature of the library it was trained for.
        info: training facts (cases, CV accuracy, chosen parameters).
    """

    pipeline: object
    kind: str
    clips: tuple
    library: str
    info: dict = field(default_factory=dict)
    _selector: object = field(default=None, init=False, repr=False, compare=False)

    def predict_features(self, x: np.ndarray) -> np.ndarray:
        """``(N,)`` clip indices for feature rows ``x (N, n)``."""
        return self.pipeline.predict(np.atleast_2d(np.asarray(x, dtype=np.float64))).astype(np.int64)

    def probabilities(self, x: np.ndarray) -> np.ndarray:
        """``(N, K)`` class probabilities over every library clip (0 for clips never seen in training)."""
        p = self.pipeline.predict_proba(np.atleast_2d(np.asarray(x, dtype=np.float64)))
        out = np.zeros((len(p), len(self.clips)))
        out[:, self.pipeline.classes_.astype(np.int64)] = p
        return out

    def selector(self):
        """The compiled :class:`kinodyn.response.selector.Selector` of this model, built once; None when
        the pipeline is of a shape it does not compile (then scikit-learn chooses). Built again when the
        pipeline is replaced."""
        if self._selector is None or self._selector[0] is not self.pipeline:
            from kinodyn.response.selector import Selector

            try:
                self._selector = (self.pipeline, Selector(self))
            except ParameterError:
                self._selector = (self.pipeline, None)
        return self._selector[1]

    def __call__(self, states) -> tuple[int, np.ndarray]:
        """The ``select`` of :func:`kinodyn.response.pipeline.respond`: clip index and probabilities for
        the states at 0.0, 0.1 and 0.2 s after contact, from the compiled :meth:`selector` (the same
        choices, the same probabilities to rounding); through scikit-learn, asked once, for a pipeline
        it does not compile (the clip is then the most probable one, which is what the calibrated
        classifier predicts)."""
        sel = self.selector()
        if sel is not None:
            return sel(states)
        probs = self.probabilities(features(states, self.kind)[None])[0]
        return int(np.argmax(probs)), probs

    def check_library(self, library) -> None:
        """Raise :class:`ParameterError` when ``library`` is not the one the model was trained for."""
        if library.signature() != self.library:
            raise ParameterError(f"the model was trained for another reaction library ({self.library[:60]}...), "
                                 f"not this one ({library.signature()[:60]}...)")

    def save(self, folder) -> None:
        """Write ``model.skops`` and ``model.json`` into ``folder`` (created), each atomically."""
        import skops.io as sio

        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        with atomic_path(folder / "model.skops", suffix=".skops") as tmp:
            sio.dump(self.pipeline, tmp)
        meta = {"format": FORMAT, "kind": self.kind, "clips": list(self.clips), "library": self.library,
                "info": self.info}
        with atomic_path(folder / "model.json", suffix=".json") as tmp:
            Path(tmp).write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")

    @classmethod
    def load(cls, folder, library=None) -> "ReactionModel":
        """Read a model written by :meth:`save`; with ``library``, check it is the model's library."""
        import skops.io as sio

        folder = Path(folder)
        try:
            meta = json.loads((folder / "model.json").read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as e:
            raise FileFormatError(f"cannot read model description: {e}", folder / "model.json") from None
        if meta.get("format") != FORMAT or meta.get("kind") not in FEATURE_SETS:
            raise FileFormatError(f"not a kinodyn response model (format {meta.get('format')!r})", folder)
        path = folder / "model.skops"
        try:
            untrusted = sio.get_untrusted_types(file=path)
        except Exception as e:  # skops raises several kinds for a damaged file
            raise FileFormatError(f"cannot read model: {e}", path) from None
        bad = [t for t in untrusted if not t.startswith(_TRUSTED_PREFIXES)]
        if bad:
            raise FileFormatError(f"model file holds types outside scikit-learn and numpy: {bad}", path)
        model = cls(sio.load(path, trusted=untrusted), meta["kind"], tuple(meta["clips"]), meta["library"],
                    meta.get("info", {}))
        if library is not None:
            model.check_library(library)
        return model


def _calibrated(params: dict, folds: int, seed: int):
    """The shipped classifier: standardize, then an SVC with ``params`` whose decision values are
    Platt-scaled on ``folds``-fold cross-validated predictions (one SVC, fitted on all cases)."""
    from sklearn.calibration import CalibratedClassifierCV
    from sklearn.model_selection import StratifiedKFold
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    svc = SVC(kernel="poly", gamma="scale", random_state=seed,
              **{k.removeprefix("svc__"): v for k, v in params.items()})
    cv = StratifiedKFold(folds, shuffle=True, random_state=seed)
    return make_pipeline(StandardScaler(), CalibratedClassifierCV(svc, method="sigmoid", cv=cv, ensemble=False))


def train(x: np.ndarray, y: np.ndarray, kind: str, library, *, folds: int = 3, seed: int = 0,
          grid: dict | None = None, errors: np.ndarray | None = None) -> ReactionModel:
    """Fit the classifier on features ``x (N, n)`` and exhaustive labels ``y (N,)`` (clip indices into
    ``library``): the SVC's parameters chosen from the grid by ``folds``-fold cross-validation, then the
    calibrated classifier with them cross-validated on the same folds and fitted on every case. Labels
    with fewer than :data:`MIN_CASES` cases are not learnt; ``cv_accuracy`` counts their cases as misses
    (it is the fraction of all ``N`` cases predicted right). With every clip's best exhaustive error
    ``errors (N, K)`` (a dataset's ``per_clip``), ``cv_choice_d_within_10pct`` is the fraction of all cases
    whose cross-validated choice has a best D within :data:`NEAR_OPTIMUM` of the optimum."""
    from sklearn.model_selection import GridSearchCV, StratifiedKFold, cross_val_predict
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.int64)
    if x.ndim != 2 or len(x) != len(y) or len(x) == 0:
        raise ParameterError(f"x must be (N, n) and y (N,) with N > 0, got {x.shape} and {y.shape}")
    if not np.all(np.isfinite(x)):
        raise ParameterError("features hold non-finite values; drop the failed cases first")
    if y.min() < 0 or y.max() >= len(library):
        raise ParameterError(f"labels must be clip indices in [0, {len(library)}), got [{y.min()}, {y.max()}]")
    counts = np.bincount(y, minlength=len(library))
    learnt = counts[y] >= MIN_CASES
    if len(np.unique(y[learnt])) < 2:
        raise ParameterError(f"training needs at least two clip labels with {MIN_CASES} or more cases each, got "
                             f"counts {counts[counts > 0].tolist()}")
    xl, yl = x[learnt], y[learnt]
    folds = int(max(2, min(folds, MIN_CASES // 2)))
    calib = int(max(2, min(CALIBRATION_FOLDS, MIN_CASES * (folds - 1) // folds)))
    cv = StratifiedKFold(folds, shuffle=True, random_state=seed)
    pipe = make_pipeline(StandardScaler(), SVC(kernel="poly", gamma="scale", random_state=seed))
    search = GridSearchCV(pipe, grid or GRID, cv=cv, n_jobs=1, refit=False)
    search.fit(xl, yl)
    params = dict(search.best_params_)
    pred = cross_val_predict(_calibrated(params, calib, seed), xl, yl, cv=cv, n_jobs=1)
    model = _calibrated(params, calib, seed).fit(xl, yl)
    left_out = [library.names[k] for k in np.flatnonzero((counts > 0) & (counts < MIN_CASES))]
    info = {"cases": int(len(x)), "cv_accuracy": float(np.sum(pred == yl) / len(y)),
            "svc_cv_accuracy": float(search.best_score_ * len(yl) / len(y)), "folds": folds,
            "calibration_folds": calib, "labels_left_out": left_out,
            "params": {k: (float(v) if isinstance(v, (int, float)) else v) for k, v in params.items()}}
    if errors is not None:
        e = np.asarray(errors, dtype=np.float64)[learnt]
        chosen = e[np.arange(len(pred)), pred]
        info["cv_choice_d_within_10pct"] = float(np.sum(chosen <= NEAR_OPTIMUM * e.min(axis=1)) / len(y))
    return ReactionModel(model, kind, tuple(library.names), library.signature(), info)

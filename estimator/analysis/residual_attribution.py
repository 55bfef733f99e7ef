"""Attribution of what is left: how well each telemetry channel alone predicts the held-out
residual (k-nearest neighbours, or the mean per value for discrete channels; held-out R²).

Cost: the k-NN learns from at most :data:`MAX_KNN_TRAIN_ROWS` training rows (evenly spaced in
the data's order beyond that), so k stays bounded and the attribution is linear in the number
of rows; smaller sets are used whole.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from sklearn.neighbors import KNeighborsRegressor

from estimator.analysis.residual_samples import ResidualOptions, Samples
from estimator.physics.model import FloatArray


@dataclass
class ChannelScore:
    channel: str
    r2: float


def _features(values: FloatArray, circular: bool) -> FloatArray:
    if circular:
        rad = np.radians(values)
        return np.column_stack([np.cos(rad), np.sin(rad)])
    sd = float(np.nanstd(values)) or 1.0
    return (values / sd).reshape(-1, 1)


_MAX_DISCRETE_VALUES = 16
#: The k-NN of one fold learns from at most this many training rows (see the module docstring).
MAX_KNN_TRAIN_ROWS = 4096


def _spread(rows: NDArray[np.intp], at_most: int) -> NDArray[np.intp]:
    """``rows``, or ``at_most`` of them evenly spaced when there are more."""
    if len(rows) <= at_most:
        return rows
    return rows[np.linspace(0, len(rows) - 1, at_most).round().astype(np.intp)]


def _group_means(x_train: FloatArray, y_train: FloatArray, x_test: FloatArray) -> FloatArray:
    """Mean of ``y_train`` per distinct ``x_train`` value, at ``x_test`` (NaN if unseen)."""
    keys, inverse = np.unique(x_train, return_inverse=True)
    means = np.bincount(inverse, weights=y_train) / np.bincount(inverse)
    idx = np.clip(np.searchsorted(keys, x_test), 0, len(keys) - 1)
    return np.where(keys[idx] == x_test, means[idx], np.nan)


def attribute(samples: Samples, resid: FloatArray, opt: ResidualOptions) -> list[ChannelScore]:
    """Held-out R² of ``resid`` predicted from each channel alone, best first: k-NN
    regression (sklearn), or the mean per value for channels with few distinct values."""
    scores = []
    for name, values in samples.channels.items():
        finite = np.isfinite(values)
        x = _features(np.where(finite, values, 0.0), name.endswith("_deg"))
        # a few distinct values (payload, flight regime): k-NN would break the many exact
        # ties by sample order; the mean residual per value is the nonparametric answer
        discrete = len(np.unique(values[finite])) <= _MAX_DISCRETE_VALUES
        predicted = np.full(len(resid), np.nan)
        baseline = np.full(len(resid), np.nan)
        for j in range(opt.folds):
            test = (samples.fold == j) & finite
            train = samples.train_rows(j, opt.guard_s) & finite
            if test.sum() == 0 or train.sum() < 20:
                continue
            baseline[test] = float(np.mean(resid[train]))
            if discrete:
                predicted[test] = _group_means(values[train], resid[train], values[test])
                predicted[test] = np.where(
                    np.isnan(predicted[test]), baseline[test], predicted[test]
                )
                continue
            learn = _spread(np.flatnonzero(train), MAX_KNN_TRAIN_ROWS)
            k = int(np.clip(round(math.sqrt(len(learn))), 10, 200))
            k = min(k, len(learn))
            knn = KNeighborsRegressor(n_neighbors=k).fit(x[learn], resid[learn])
            predicted[test] = knn.predict(x[test])
        ok = np.isfinite(predicted)
        if ok.sum() < 20:
            continue
        sse = float(np.sum((resid[ok] - predicted[ok]) ** 2))
        sst = float(np.sum((resid[ok] - baseline[ok]) ** 2))
        scores.append(ChannelScore(name, 1.0 - sse / sst if sst > 0 else 0.0))
    return sorted(scores, key=lambda c: -c.r2)

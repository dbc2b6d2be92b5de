#pragma once
/** \file InformedMeasure.h
 *  \brief Lebesgue measures used by LIT*'s features and by the FIT* batch rule. */

namespace lit
{
    /** \brief Volume of the unit n-ball, zeta_n = pi^(n/2) / Gamma(n/2 + 1). */
    double unitBallMeasure(unsigned int n);

    /** \brief Measure of the path-length informed set {x : |x - s| + |x - g| <= c} in R^n, an n-dimensional
     *  prolate hyperspheroid: zeta_n * (c/2) * (sqrt(c^2 - cmin^2)/2)^(n-1), capped at \e spaceMeasure.
     *  Returns \e spaceMeasure for an infinite cost and 0 when c <= cmin. */
    double informedMeasure(unsigned int n, double cost, double cmin, double spaceMeasure);

    /** \brief LIT*'s measure feature m = (lambda(X_f) / lambda(X))^(1/n), in [0, 1]. */
    double measureFeature(unsigned int n, double informed, double spaceMeasure);
}  // namespace lit

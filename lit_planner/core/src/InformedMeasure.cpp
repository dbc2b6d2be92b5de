#include "lit/InformedMeasure.h"

#include <algorithm>
#include <cmath>

namespace lit
{
    double unitBallMeasure(unsigned int n)
    {
        const double half = 0.5 * static_cast<double>(n);
        return std::exp(half * std::log(M_PI) - std::lgamma(half + 1.0));
    }

    double informedMeasure(unsigned int n, double cost, double cmin, double spaceMeasure)
    {
        if (!std::isfinite(cost))
            return spaceMeasure;
        if (cost <= cmin)
            return 0.0;
        const double transverse = 0.5 * cost;
        const double conjugate = 0.5 * std::sqrt(cost * cost - cmin * cmin);
        // Computed in log space: in R^16 the product spans many orders of magnitude.
        const double logMeasure = std::log(unitBallMeasure(n)) + std::log(transverse) +
                                  static_cast<double>(n - 1u) * std::log(conjugate);
        return std::min(std::exp(logMeasure), spaceMeasure);
    }

    double measureFeature(unsigned int n, double informed, double spaceMeasure)
    {
        if (!(spaceMeasure > 0.0))
            return 1.0;
        const double ratio = std::clamp(informed / spaceMeasure, 0.0, 1.0);
        return std::pow(ratio, 1.0 / static_cast<double>(n));
    }
}  // namespace lit

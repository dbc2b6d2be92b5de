#pragma once
/** \file litstar/RandomGeometricGraph.h
 *  \brief LIT*'s sample sets: valid samples (the k-nearest RGG), invalid samples (kept for the features),
 *  informed batch sampling, pruning, and the observation features.
 *
 *  Nearest neighbours are exact linear scans over the samples' packed coordinates with per-state caches that are
 *  extended incrementally by each new batch and that serve any smaller k as a prefix (a learned psi_K changes k
 *  at every expansion). Profiling GNAT here (np8, 2 s) showed 70% of the planner's time in
 *  GNAT's virtual distance calls: in R^8..R^16 it visits nearly every point anyway, and every batch invalidated
 *  every cache. */

#include "lit/litstar/InformedSampler.h"
#include "lit/litstar/State.h"

#include <ompl/base/SpaceInformation.h>

#include <cmath>
#include <cstring>
#include <cstdint>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

namespace lit::litstar
{
    /** \brief The point at \e t on the segment \e from -> \e to in R^dim, computed as OMPL's
     *  RealVectorStateSpace::interpolate computes it, term for term, so to the bit (the core is built with
     *  -ffp-contract=off; OMPL's Debian build has no fused multiply-adds either). */
    inline void interpolateAsOmpl(const double *from, const double *to, double t, double *out, unsigned int dim)
    {
        for (unsigned int i = 0; i < dim; ++i)
            out[i] = from[i] + (to[i] - from[i]) * t;
    }

    /** \brief A read-only view of the first entries of a state's neighbour cache, with their distances. */
    class NeighbourRange
    {
    public:
        NeighbourRange(State *const *first, const double *distances, std::size_t size)
          : first_(first), distances_(distances), size_(size)
        {
        }
        State *const *begin() const
        {
            return first_;
        }
        State *const *end() const
        {
            return first_ + size_;
        }
        std::size_t size() const
        {
            return size_;
        }
        bool empty() const
        {
            return size_ == 0u;
        }
        State *front() const
        {
            return *first_;
        }
        State *operator[](std::size_t i) const
        {
            return first_[i];
        }
        /** \brief The distances of the entries (bit-identical to RandomGeometricGraph::distance()). */
        const double *distances() const
        {
            return distances_;
        }

    private:
        State *const *first_;
        const double *distances_;
        std::size_t size_;
    };

    class RandomGeometricGraph
    {
    public:
        RandomGeometricGraph(const ompl::base::SpaceInformationPtr &si, std::uint_fast32_t seed);
        ~RandomGeometricGraph();
        RandomGeometricGraph(const RandomGeometricGraph &) = delete;
        RandomGeometricGraph &operator=(const RandomGeometricGraph &) = delete;

        /** \brief Removes every sample. */
        void clear();

        /** \brief Adds the starts and the goals (valid states, copied) and sets the sampler's foci. */
        void setTerminals(const std::vector<const ompl::base::State *> &starts,
                          const std::vector<const ompl::base::State *> &goals);
        /** \brief Adds the start and the goals (valid states, copied) and sets the sampler's foci. */
        void setTerminals(const ompl::base::State *start, const std::vector<const ompl::base::State *> &goals)
        {
            setTerminals(std::vector<const ompl::base::State *>{start}, goals);
        }

        /** \brief Adds more goals (valid states, copied) to a graph whose terminals are set: the sampler's foci and
         *  every sample's cost-to-go lower bound take them in. */
        void addGoals(const std::vector<const ompl::base::State *> &goals);

        /** \brief Draws samples from the informed set of \e maxCost until \e batchSize valid ones were added;
         *  invalid draws are kept in X_invalid. \e stop (if given) is asked every STOP_CHECK_INTERVAL draws and
         *  ends the batch early when true. At most MAX_DRAWS_PER_SAMPLE * \e batchSize draws are made: a set almost
         *  all in collision ends the batch with fewer (a run limited by iterations alone never ended). Returns the
         *  number of valid samples added. */
        std::size_t addBatch(std::size_t batchSize, double maxCost, const std::function<bool()> &stop = {});
        static constexpr std::size_t STOP_CHECK_INTERVAL = 64u;
        static constexpr std::size_t MAX_DRAWS_PER_SAMPLE = 1000u;
        /** \brief Whether the last addBatch() ended at its draw limit, short of its samples. */
        bool lastBatchCapped() const
        {
            return lastBatchCapped_;
        }

        /** \brief Adds a valid sample at \e x (no validity check; for tests and hand-built graphs). */
        State *addValidSample(const std::vector<double> &x);

        /** \brief Adds an invalid sample at \e x (no validity check; for tests and hand-built graphs). */
        void addInvalidSample(const std::vector<double> &x);

        /** \brief Removes samples that cannot improve a solution of cost \e maxCost (heuristic > maxCost), except
         *  the terminals and pinned samples.
         *  \e beforeRemove runs on each valid state first. Returns the number of samples removed. */
        std::size_t prune(double maxCost, const std::function<void(State *)> &beforeRemove);

        /** \brief The k nearest valid samples of \e state (itself excluded, and for a goal every goal: no search
         *  uses an edge between two goals; sorted by distance, ties by id).
         *  Cached per state and updated incrementally with the samples added since; a smaller k than cached is a
         *  prefix of the cache, a larger one rescans, a prune filters the cache. The range stays valid until the
         *  next call for \e state or the next prune. */
        NeighbourRange neighbours(State *state, std::size_t k);

        /** \brief The samples that have \e state among their k nearest as last asked for (the reverse direction of
         *  neighbours()); together they make the lists computed so far symmetric (samples whose own list was never
         *  asked for add no edges: not the full undirected k-nearest graph). */
        const std::vector<State *> &incomingNeighbours(State *state);
        /** \brief The distances of incomingNeighbours(state) as it last returned them, in its order. */
        const std::vector<double> &incomingDistances(const State *state) const
        {
            return state->incomingDistances_;
        }

        /** \brief Euclidean distance between two samples. */
        double distance(const State *a, const State *b) const
        {
            return distance(a->coordinates_, b->coordinates_);
        }
        double distance(const double *a, const double *b) const
        {
            return std::sqrt(squaredDistance(a, b));
        }
        /** \brief The sum that distance() takes the sqrt of. The neighbour scans and the local ratios use this
         *  one function too, so their sums are the same to the bit as distance()'s. */
        double squaredDistance(const double *a, const double *b) const
        {
            double sum = 0.0;
            for (unsigned int i = 0; i < dim_; ++i)
                sum += (a[i] - b[i]) * (a[i] - b[i]);
            return sum;
        }

        /** \brief squaredDistance() of \e a to the four points packed at \e b (dim values each), bit-identical to
         *  four calls: each sum is added in the same order, the four side by side. */
        void squaredDistances4(const double *a, const double *b, double *sums) const
        {
            const double *b1 = b + dim_, *b2 = b1 + dim_, *b3 = b2 + dim_;
            double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
            for (unsigned int i = 0; i < dim_; ++i)
            {
                s0 += (a[i] - b[i]) * (a[i] - b[i]);
                s1 += (a[i] - b1[i]) * (a[i] - b1[i]);
                s2 += (a[i] - b2[i]) * (a[i] - b2[i]);
                s3 += (a[i] - b3[i]) * (a[i] - b3[i]);
            }
            sums[0] = s0;
            sums[1] = s1;
            sums[2] = s2;
            sums[3] = s3;
        }

        /** \brief rho = |X_invalid| / (|X_valid| + |X_invalid|) (Eq. 4 of the paper); 0 without samples. */
        double ratioCalc() const;

        /** \brief Invalid ratio among the samples within \e radius of \e centre, not counting samples at
         *  the centre's own position (distance 0: a state is not its own neighbour); negative when there are
         *  none. */
        double localRatio(const ompl::base::State *centre, double radius) const;

        /** \brief Algorithm 2: (rho_local,B, rho_local,K): the mean local ratio over \e pathStates (rho_global
         *  when empty) and the local ratio at \e centre (rho_global when its neighbourhood is empty or it is null). */
        std::pair<double, double> localRatioCalc(const std::vector<const ompl::base::State *> &pathStates,
                                                 const ompl::base::State *centre, double radius) const;

        /** \brief The RGG radius r = eta (2 (1 + 1/n) (lambda(X_f) / zeta_n) (ln q / q))^(1/n), q = |X_valid|. */
        double radius(double rewireFactor, double informedMeasure) const;

        std::size_t numValid() const
        {
            return states_.size();
        }
        std::size_t numInvalid() const
        {
            return packedInvalid_.size() / dim_;
        }
        /** \brief Draws rejected by the validity checker since the last clear (kept or later pruned). */
        std::size_t invalidDraws() const
        {
            return invalidDraws_;
        }
        std::size_t validDraws() const
        {
            return validDraws_;
        }
        std::size_t version() const
        {
            return version_;
        }
        /** \brief The first start state (null before setTerminals()): the features' reference. */
        State *start() const
        {
            return starts_.empty() ? nullptr : starts_.front();
        }
        const std::vector<State *> &starts() const
        {
            return starts_;
        }
        const std::vector<State *> &goals() const
        {
            return goals_;
        }
        const std::vector<std::unique_ptr<State>> &states() const
        {
            return states_;
        }
        const InformedSampler &sampler() const
        {
            return sampler_;
        }

    private:
        State *createState(ompl::base::State *raw);
        /** \brief Appends a point's dim_ coordinates to a packed array. */
        void appendPacked(std::vector<double> &packed, const double *x) const;
        void computeLowerBounds(State *state) const;
        /** \brief Whether \e state, at \e distance from \e owner, is among the k nearest that \e owner was last
         *  asked for, given that it was at some point since the last prune. */
        bool inAskedPrefix(const State *owner, const State *state, double distance) const;
        /** \brief How many of the packed points lie within \e radius of \e centre (as distance() <= radius),
         *  not counting points at \e centre itself. */
        std::size_t countWithin(const std::vector<double> &packed, const double *centre, double radius) const;
        /** \brief Merges states_[from, end) into \e state's cache of its \e cap nearest. */
        void scanNeighbours(State *state, std::size_t cap, std::size_t from);
        static const double *coordinatesOf(const ompl::base::State *raw);

        ompl::base::SpaceInformationPtr si_;
        InformedSampler sampler_;
        std::vector<std::unique_ptr<State>> states_;
        /** \brief The valid samples' coordinates, dim_ per sample, in the order of states_ (for linear scans). */
        std::vector<double> packed_;
        /** \brief In R^9 and up (floatFilter_), packed_ in single precision, each row padded with zeros to
         *  floatStride_ (a multiple of 4) values: a cheap filter in scanNeighbours, whose sums (with a bound on their
         *  error) drop most samples before the exact double sum. maxAbsCoordinate_ bounds |x_i| over these rows, or
         *  is NaN after a NaN coordinate (it only grows until a clear or prune). In R^8 and below the double sums
         *  cost about what the filter does (measured slower on np8 and rrd8), and packedFloat_ stays empty. */
        bool floatFilter_;
        std::vector<float> packedFloat_;
        unsigned int floatStride_;
        double maxAbsCoordinate_{0.0};
        std::vector<float> queryFloat_;
        /** \brief Appends a valid sample's coordinates to packed_ (and packedFloat_). */
        void appendValid(const double *x);
        /** \brief The sums of squared differences of row \e a to the four rows of packedFloat_ at \e b (any order
         *  of additions: a filter only). */
        void floatSquaredDistances4(const float *a, const float *b, float *sums) const
        {
#if defined(__GNUC__)
            typedef float Float4 __attribute__((vector_size(16)));
            Float4 acc[4] = {};
            for (unsigned int i = 0; i < floatStride_; i += 4u)
            {
                Float4 x;
                std::memcpy(&x, a + i, sizeof x);
                for (unsigned int j = 0; j < 4u; ++j)
                {
                    Float4 y;
                    std::memcpy(&y, b + j * floatStride_ + i, sizeof y);
                    const Float4 d = x - y;
                    acc[j] += d * d;
                }
            }
            for (unsigned int j = 0; j < 4u; ++j)
                sums[j] = (acc[j][0] + acc[j][1]) + (acc[j][2] + acc[j][3]);
#else
            for (unsigned int j = 0; j < 4u; ++j)
            {
                float sum = 0.0f;
                for (unsigned int i = 0; i < floatStride_; ++i)
                {
                    const float d = a[i] - b[j * floatStride_ + i];
                    sum += d * d;
                }
                sums[j] = sum;
            }
#endif
        }
        /** \brief The invalid samples' coordinates, dim_ per sample: all that is kept of them (for the invalid
         *  ratios and the prune). An OMPL state each, as they used to be kept as well, took about 190 more bytes per
         *  sample in R^16 (an unsolvable query keeps every invalid draw) and two allocations per draw. */
        std::vector<double> packedInvalid_;
        unsigned int dim_;
        /** \brief Incremented by clear(); neighbour caches of an older epoch are recomputed. (A prune filters
         *  the caches instead.) */
        std::size_t cacheEpoch_{0u};
        /** \brief Incremented by every prune that removes samples, which clears the incoming lists: a state
         *  registers its prefix in them again when next asked. */
        std::size_t incomingEpoch_{0u};
        std::vector<State *> starts_;
        std::vector<State *> goals_;
        std::size_t nextId_{0u};
        std::size_t version_{0u};
        std::size_t invalidDraws_{0u};
        std::size_t validDraws_{0u};
        bool lastBatchCapped_{false};
        /** \brief Scratch buffers of scanNeighbours (kept to avoid an allocation per scan). */
        std::vector<std::pair<double, State *>> candidates_;
        std::vector<std::pair<double, State *>> merged_;
    };
}  // namespace lit::litstar

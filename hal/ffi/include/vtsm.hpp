// vtsm.hpp: a header-only C++17 wrapper over vtsm.h for F Prime components
// and other C++ flight code. RAII over the caller's storage: an Engine sets
// itself up in a buffer the caller owns (a member or a static) and releases
// it on destruction. No exceptions, no heap, no RTTI: every fallible call
// returns a vtsm::Code, and results are std::array views.
#ifndef VTSM_HPP
#define VTSM_HPP

#include <array>
#include <cstddef>
#include <cstdint>

#include "vtsm.h"

namespace vtsm {

/// A failure code (VtsmFailure); VTSM_OK is 0.
struct Code {
    std::uint16_t value;
    constexpr bool ok() const noexcept { return value == VTSM_OK; }
    const char *name() const noexcept { return vtsm_failure_name(value); }
};

/// Engine storage of N bytes with the alignment the engine needs; N is one
/// of the VTSM_STORAGE_BYTES_* constants or vtsm_storage_size's answer.
template <std::size_t N>
struct alignas(VTSM_STORAGE_ALIGN) Storage {
    std::array<std::uint8_t, N> bytes;
};

/// The parameters of a named profile.
inline Code params_for_profile(VtsmProfile profile, VtsmParams &out) noexcept {
    return Code{vtsm_params_for_profile(static_cast<std::uint32_t>(profile), &out)};
}

/// The result of a run, with std::array views of the pose and covariance.
class Outcome {
public:
    Outcome() noexcept : raw_{} {}
    explicit Outcome(const VtsmOutcome &raw) noexcept : raw_(raw) {}
    Code failure() const noexcept { return Code{raw_.failure}; }
    bool ok() const noexcept { return raw_.failure == VTSM_OK; }
    std::array<float, 3> translation() const noexcept { return {raw_.t[0], raw_.t[1], raw_.t[2]}; }
    std::array<float, 4> rotation_wxyz() const noexcept {
        return {raw_.q[0], raw_.q[1], raw_.q[2], raw_.q[3]};
    }
    std::array<float, 36> covariance() const noexcept {
        std::array<float, 36> c{};
        for (std::size_t i = 0; i < c.size(); ++i) c[i] = raw_.covariance[i];
        return c;
    }
    const VtsmStats &stats() const noexcept { return raw_.stats; }
    const VtsmOutcome &raw() const noexcept { return raw_; }

private:
    VtsmOutcome raw_;
};

/// An engine in caller storage: created by the constructor (check
/// `status()`), released by the destructor. Not copyable or movable: the
/// handle points into the storage.
template <std::size_t N>
class Engine {
public:
    Engine(Storage<N> &storage, const VtsmConfig &config) noexcept : storage_(storage), handle_(nullptr) {
        status_ = Code{vtsm_engine_create(storage_.bytes.data(), N, &config, &handle_)};
    }
    ~Engine() { vtsm_engine_release(handle_); }
    Engine(const Engine &) = delete;
    Engine &operator=(const Engine &) = delete;
    Engine(Engine &&) = delete;
    Engine &operator=(Engine &&) = delete;

    /// VTSM_OK when the engine is set up; else why not (then run() refuses).
    Code status() const noexcept { return status_; }

    /// One relocalization under `limits`; `out` holds the outcome whenever
    /// the returned code is VTSM_OK.
    Code run(const VtsmLimits &limits, Outcome &out) noexcept {
        VtsmOutcome raw{};
        Code c{vtsm_engine_run(handle_, &limits, &raw)};
        out = Outcome(raw);
        return c;
    }

    /// Start one relocalization under `limits` (the step and tick limits;
    /// the work per call is step()'s).
    Code start(const VtsmLimits &limits) noexcept { return Code{vtsm_engine_start(handle_, &limits)}; }

    /// At most `max_units` units of work (a rate group's budget per
    /// period); `done` is then whether outcome() may be taken.
    Code step(std::uint32_t max_units, bool &done) noexcept {
        VtsmStepStatus s = VTSM_STEP_RUNNING;
        Code c{vtsm_engine_step(handle_, max_units, &s)};
        done = s == VTSM_STEP_DONE;
        return c;
    }

    /// End the relocalization under way; `out` holds the outcome whenever
    /// the returned code is VTSM_OK.
    Code outcome(Outcome &out) noexcept {
        VtsmOutcome raw{};
        Code c{vtsm_engine_outcome(handle_, &raw)};
        out = Outcome(raw);
        return c;
    }

private:
    Storage<N> &storage_;
    VtsmEngine *handle_;
    Code status_{VTSM_OK};
};

}  // namespace vtsm

#endif  // VTSM_HPP

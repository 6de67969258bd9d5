// The C++17 wrapper (hal/ffi/include/vtsm.hpp) exercised: the scene through
// vtsm::Engine over caller storage, then the release on scope exit.
#include <cstdio>
#include <cstring>
#include <new>

#include "vtsm.hpp"

extern "C" {
#include "harness.h"
}

extern "C" int cpp_wrapper_run(std::uint8_t *storage, std::size_t storage_len, std::uint64_t *digest) {
    int failed = 0;
    if (storage_len < VTSM_STORAGE_BYTES_TEST) return 1;
    // The harness's static storage viewed as the wrapper's storage type
    // (same size and alignment).
    auto &st = *reinterpret_cast<vtsm::Storage<VTSM_STORAGE_BYTES_TEST> *>(storage);
    Devices dev = scene_devices();
    VtsmConfig cfg = scene_config(&dev);
    VtsmEngine *stale = nullptr;
    {
        vtsm::Engine<VTSM_STORAGE_BYTES_TEST> engine(st, cfg);
        if (!engine.status().ok()) {
            std::printf("c++: create failed: %s\n", engine.status().name());
            return 1;
        }
        vtsm::Outcome out;
        VtsmLimits limits{16u, UINT32_MAX, UINT64_MAX};
        vtsm::Code rc = engine.run(limits, out);
        if (!rc.ok()) {
            std::printf("c++: run failed: %s\n", rc.name());
            return 1;
        }
        std::array<float, 3> t = out.translation();
        std::array<float, 36> cov = out.covariance();
        std::printf("c++: outcome %s, t = (%.4f, %.4f, %.4f), var(x) = %.3g\n", out.failure().name(),
                    static_cast<double>(t[0]), static_cast<double>(t[1]), static_cast<double>(t[2]),
                    static_cast<double>(cov[0]));
        *digest = outcome_digest(&out.raw());
        // The same relocalization stepped, 3 units per call.
        bool done = false;
        rc = engine.start(limits);
        for (unsigned long i = 0; rc.ok() && !done && i < 100000ul; i++) rc = engine.step(3u, done);
        if (rc.ok()) rc = engine.outcome(out);
        if (!rc.ok() || outcome_digest(&out.raw()) != *digest) {
            std::printf("c++: stepped run differs: %s\n", rc.name());
            failed++;
        }
        stale = reinterpret_cast<VtsmEngine *>(storage);
    }
    // After the wrapper's scope the storage holds no engine.
    VtsmOutcome raw;
    std::uint16_t rc = vtsm_engine_run(stale, nullptr, &raw);
    std::printf("c++: run after release -> %s\n", vtsm_failure_name(rc));
    if (rc != VTSM_FFI_BAD_HANDLE) failed++;
    return failed;
}

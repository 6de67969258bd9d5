/* The C harness: runs the CI flight-path scene through the C interface
 * (vtsm.h, libvtsm_ffi.a) and prints its digest, then the bad-input checks
 * and the C++ wrapper. The same source runs on the host (under ASan and
 * UBSan) and on the Cortex-M7 under QEMU (newlib, semihosting). */
#include <stdio.h>
#include <string.h>
#include "harness.h"
#include "scene.h"

/* The engine storage: static, aligned, sized by the header's constant. */
static uint8_t storage[VTSM_STORAGE_BYTES_TEST] __attribute__((aligned(VTSM_STORAGE_ALIGN)));

/* A RAM copy of the map product for the bad-input checks. */
uint8_t map_copy[SCENE_MAP_LEN] __attribute__((aligned(16)));
const size_t map_copy_len = sizeof map_copy;

int32_t dev_read_window(void *ctx, uint8_t eye, int32_t x, int32_t y, uint32_t w, uint32_t h,
                        uint8_t *out, size_t out_len) {
    Devices *d = (Devices *)ctx;
    const uint8_t *frame = eye == VTSM_EYE_LEFT ? d->left : eye == VTSM_EYE_RIGHT ? d->right : NULL;
    if (d->fail_windows) return VTSM_IO_CORRUPTED;
    if (frame == NULL || out == NULL || x < 0 || y < 0 || w == 0 || h == 0) return VTSM_IO_OTHER;
    if ((uint64_t)(uint32_t)x + w > d->width || (uint64_t)(uint32_t)y + h > d->height) return VTSM_IO_OTHER;
    if ((uint64_t)w * h > out_len) return VTSM_IO_OTHER;
    uint64_t t0 = platform_ticks();
    for (uint32_t r = 0; r < h; r++)
        memcpy(out + (size_t)r * w, frame + ((size_t)(uint32_t)y + r) * d->width + (uint32_t)x, w);
    d->window_ticks += platform_ticks() - t0;
    d->windows++;
    return VTSM_IO_OK;
}

int32_t dev_latch(void *ctx) {
    ((Devices *)ctx)->latches++;
    return VTSM_IO_OK;
}

int32_t dev_read_map(void *ctx, uint32_t offset, uint8_t *buf, size_t len) {
    Devices *d = (Devices *)ctx;
    if (buf == NULL || offset > d->map_len || len > d->map_len - offset) return VTSM_IO_OTHER;
    memcpy(buf, d->map + offset, len);
    return VTSM_IO_OK;
}

int32_t dev_write_telemetry(void *ctx, uint8_t kind, const uint8_t *payload, size_t len) {
    Devices *d = (Devices *)ctx;
    (void)kind;
    if (payload == NULL && len > 0) return VTSM_IO_OTHER;
    d->telemetry_frames++;
    d->telemetry_bytes += (uint32_t)len;
    return VTSM_IO_OK;
}

uint64_t dev_now(void *ctx) {
    (void)ctx;
    return platform_ticks();
}

Devices scene_devices(void) {
    Devices d;
    memset(&d, 0, sizeof d);
    d.left = scene_left;
    d.right = scene_right;
    d.width = SCENE_WIDTH;
    d.height = SCENE_HEIGHT;
    d.map = scene_map;
    d.map_len = (size_t)(scene_map_end - scene_map);
    return d;
}

VtsmConfig scene_config(Devices *dev) {
    VtsmConfig c;
    memset(&c, 0, sizeof c);
    c.map = scene_map;
    c.map_len = (size_t)(scene_map_end - scene_map);
    c.rig.fx = SCENE_CAMERA[0];
    c.rig.fy = SCENE_CAMERA[1];
    c.rig.cx = SCENE_CAMERA[2];
    c.rig.cy = SCENE_CAMERA[3];
    c.rig.width = SCENE_WIDTH;
    c.rig.height = SCENE_HEIGHT;
    c.rig.baseline_m = SCENE_BASELINE_M;
    (void)vtsm_params_for_profile(VTSM_PROFILE_TEST, &c.params);
    memcpy(c.prior.t, SCENE_PRIOR, sizeof c.prior.t);
    memcpy(c.prior.q, SCENE_PRIOR + 3, sizeof c.prior.q);
    /* 0.2 m and 1.5 degrees (1 sigma), as the Rust flight image's prior. */
    for (int i = 0; i < 6; i++)
        c.prior.covariance[i * 7] = i < 3 ? 0.2f * 0.2f : (1.5f * 0.017453292f) * (1.5f * 0.017453292f);
    c.seed = SCENE_SEED;
    c.io.ctx = dev;
    c.io.read_window = dev_read_window;
    c.io.latch = dev_latch;
    c.io.read_map = dev_read_map;
    c.io.write_telemetry = dev_write_telemetry;
    c.io.now_ticks = dev_now;
    c.io.tick_hz = 1000000u;
    return c;
}

static uint64_t fold(uint64_t h, const uint8_t *b, size_t n) {
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 0x00000100000001b3ull;
    }
    return h;
}

static uint64_t fold_u64(uint64_t h, uint64_t v) {
    uint8_t b[8];
    for (int i = 0; i < 8; i++) b[i] = (uint8_t)(v >> (8 * i));
    return fold(h, b, 8);
}

static uint64_t fold_f32(uint64_t h, float f) {
    uint32_t bits;
    uint8_t b[4];
    memcpy(&bits, &f, 4);
    for (int i = 0; i < 4; i++) b[i] = (uint8_t)(bits >> (8 * i));
    return fold(h, b, 4);
}

uint64_t outcome_digest(const VtsmOutcome *o) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (int i = 0; i < 3; i++) h = fold_f32(h, o->t[i]);
    for (int i = 0; i < 4; i++) h = fold_f32(h, o->q[i]);
    h = fold_f32(h, o->rms_m);
    h = fold_u64(h, o->inliers);
    h = fold_u64(h, o->stats.attempts);
    h = fold_u64(h, o->stats.ransac_iterations);
    h = fold_u64(h, o->stats.ncc_macs);
    h = fold_u64(h, o->failure);
    return h;
}

/* One relocalization of `c` to completion in the static storage: the
 * create's code when it fails, else the run's. */
static uint16_t run_config(const VtsmConfig *c, const VtsmLimits *limits, VtsmOutcome *out) {
    VtsmEngine *engine = NULL;
    uint16_t rc = vtsm_engine_create(storage, sizeof storage, c, &engine);
    if (rc == VTSM_OK) rc = vtsm_engine_run(engine, limits, out);
    return rc;
}

int main(void) {
    int failed = 0;
    Devices dev = scene_devices();
    VtsmConfig cfg = scene_config(&dev);
    VtsmEngine *engine = NULL;
    size_t need = vtsm_storage_size(&cfg.params);
    printf("storage: %lu bytes needed, %lu given (VTSM_STORAGE_BYTES_TEST)\n",
           (unsigned long)need, (unsigned long)sizeof storage);
    uint16_t rc = vtsm_engine_create(storage, sizeof storage, &cfg, &engine);
    if (rc != VTSM_OK) {
        printf("create failed: %s\n", vtsm_failure_name(rc));
        return 1;
    }
    VtsmLimits limits = {16u, UINT32_MAX, UINT64_MAX};
    VtsmOutcome out;
    uint64_t per_tick = platform_instructions_per_tick();
    uint64_t t0 = platform_ticks();
    rc = vtsm_engine_run(engine, &limits, &out);
    uint64_t t1 = platform_ticks();
    if (rc != VTSM_OK) {
        printf("run failed: %s\n", vtsm_failure_name(rc));
        return 1;
    }
    uint64_t digest = outcome_digest(&out);
    printf("outcome: %s, inliers %u, attempts %lu, steps %lu, windows %lu, telemetry %lu frames %lu bytes\n",
           vtsm_failure_name(out.failure), (unsigned)out.inliers, (unsigned long)out.stats.attempts,
           (unsigned long)out.stats.steps, (unsigned long)dev.windows,
           (unsigned long)dev.telemetry_frames, (unsigned long)dev.telemetry_bytes);
    /* As the Rust flight image counts: the runner's drive, first engine
     * step to last (stats.elapsed_ticks), in instructions. */
    printf("VTSM-C-INSTRUCTIONS engine %llu, whole run %llu (%llu per tick)\n",
           (unsigned long long)(out.stats.elapsed_ticks * per_tick),
           (unsigned long long)((t1 - t0) * per_tick), (unsigned long long)per_tick);
    printf("VTSM-C-WINDOW-INSTRUCTIONS %llu in %lu reads (the C callback's copies)\n",
           (unsigned long long)(dev.window_ticks * per_tick), (unsigned long)dev.windows);
    printf("VTSM-C-DIGEST %016llx (rust %016llx)\n", (unsigned long long)digest,
           (unsigned long long)SCENE_RUST_DIGEST);
    if (digest != SCENE_RUST_DIGEST) failed++;

    /* The same relocalization stepped as a rate group would: start, then a
     * small work budget per period until done, then the outcome. */
    rc = vtsm_engine_start(engine, &limits);
    unsigned long periods = 0;
    VtsmStepStatus status = VTSM_STEP_RUNNING;
    while (rc == VTSM_OK && status == VTSM_STEP_RUNNING && periods < 100000ul) {
        rc = vtsm_engine_step(engine, 2u, &status);
        periods++;
    }
    if (rc == VTSM_OK) rc = vtsm_engine_outcome(engine, &out);
    uint64_t stepped = rc == VTSM_OK ? outcome_digest(&out) : 0;
    printf("VTSM-C-STEPPED-DIGEST %016llx in %lu periods of 2 units (%s)\n", (unsigned long long)stepped,
           periods, vtsm_failure_name(rc));
    if (stepped != digest) failed++;

    /* The caller's accuracy: a loose one (2 cm, 0.5 degrees) ends the rounds
     * after the first pose update whose refined estimate states it. */
    VtsmConfig loose = cfg;
    loose.accuracy_sigma_t_m = 0.02f;
    loose.accuracy_sigma_r_deg = 0.5f;
    VtsmOutcome early;
    rc = run_config(&loose, &limits, &early);
    printf("VTSM-C-ACCURACY %s: %s, %u pose updates, %u saved, attempts %lu (all updates: %lu)\n",
           vtsm_failure_name(rc), vtsm_failure_name(early.failure), (unsigned)early.stats.successes,
           (unsigned)early.stats.rounds_saved, (unsigned long)early.stats.attempts,
           (unsigned long)out.stats.attempts);
    if (rc != VTSM_OK || early.failure != VTSM_OK || early.stats.rounds_saved == 0 ||
        early.stats.attempts >= out.stats.attempts || out.stats.rounds_saved != 0)
        failed++;

    /* More correspondences in the last round: the same success, more
     * attempts than with N_corr, and the engine's inliers can exceed N_corr. */
    VtsmConfig wide = cfg;
    wide.final_pairs = (uint16_t)(cfg.params.n_corr + cfg.params.n_corr / 2u);
    VtsmOutcome more;
    rc = run_config(&wide, &limits, &more);
    printf("VTSM-C-FINAL-PAIRS %s: %s, final_pairs %u, %lu attempts (N_corr: %lu), %u inliers\n",
           vtsm_failure_name(rc), vtsm_failure_name(more.failure), (unsigned)wide.final_pairs,
           (unsigned long)more.stats.attempts, (unsigned long)out.stats.attempts, (unsigned)more.inliers);
    if (rc != VTSM_OK || more.failure != VTSM_OK || more.stats.attempts <= out.stats.attempts)
        failed++;

    /* The search mechanisms: the default (zeroed fields) runs Revisit and
     * not Near; Revisit off measures no revisit vertex; Near on draws near
     * agreeing vertices. Each is a success on this scene. */
    VtsmConfig plain = cfg;
    plain.revisit_off = 1u;
    VtsmOutcome off;
    rc = run_config(&plain, &limits, &off);
    printf("VTSM-C-REVISIT-OFF %s: %s, revisited %lu (default: %lu), near %lu, %lu attempts (default: %lu)\n",
           vtsm_failure_name(rc), vtsm_failure_name(off.failure), (unsigned long)off.stats.revisited,
           (unsigned long)out.stats.revisited, (unsigned long)off.stats.near_drawn,
           (unsigned long)off.stats.attempts, (unsigned long)out.stats.attempts);
    if (rc != VTSM_OK || off.failure != VTSM_OK || off.stats.revisited != 0 || out.stats.revisited == 0 ||
        out.stats.near_drawn != 0 || off.stats.near_drawn != 0)
        failed++;
    VtsmConfig nearby = cfg;
    nearby.near_on = 1u;
    VtsmOutcome drawn_near;
    rc = run_config(&nearby, &limits, &drawn_near);
    printf("VTSM-C-NEAR %s: %s, near %lu, revisited %lu, %lu attempts (default: %lu)\n",
           vtsm_failure_name(rc), vtsm_failure_name(drawn_near.failure), (unsigned long)drawn_near.stats.near_drawn,
           (unsigned long)drawn_near.stats.revisited, (unsigned long)drawn_near.stats.attempts,
           (unsigned long)out.stats.attempts);
    if (rc != VTSM_OK || drawn_near.failure != VTSM_OK || drawn_near.stats.near_drawn == 0 || drawn_near.stats.revisited == 0)
        failed++;

    failed += bad_input_tests(storage, sizeof storage);

    uint64_t cpp_digest = 0;
    failed += cpp_wrapper_run(storage, sizeof storage, &cpp_digest);
    printf("VTSM-CPP-DIGEST %016llx\n", (unsigned long long)cpp_digest);
    if (cpp_digest != digest) failed++;

    printf("VTSM-C-RESULT %s (%d failed)\n", failed ? "FAIL" : "PASS", failed);
    return failed ? 1 : 0;
}

/* Bad inputs at the C boundary: every one gets its documented code, none
 * crashes (the host build runs under ASan and UBSan). */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "harness.h"

/* Zeroed storage that never held an engine. */
static uint8_t blank[2048] __attribute__((aligned(16)));

static int failures;

static void expect(const char *what, uint16_t got, uint16_t want) {
    int ok = got == want;
    printf("bad input: %-44s -> %-28s %s\n", what, vtsm_failure_name(got), ok ? "ok" : "WRONG");
    if (!ok) {
        printf("  expected %s\n", vtsm_failure_name(want));
        failures++;
    }
}

static uint16_t create_with(uint8_t *storage, size_t len, const VtsmConfig *cfg) {
    VtsmEngine *e = (VtsmEngine *)1; /* must be reset to NULL on failure */
    uint16_t rc = vtsm_engine_create(storage, len, cfg, &e);
    if (rc != VTSM_OK && e != NULL) {
        printf("  engine_out not cleared on failure\n");
        failures++;
    }
    return rc;
}

int bad_input_tests(uint8_t *storage, size_t storage_len) {
    Devices dev = scene_devices();
    const VtsmConfig good = scene_config(&dev);
    VtsmConfig c;
    VtsmEngine *e = NULL;
    VtsmOutcome out;
    size_t map_len = good.map_len;
    failures = 0;

    expect("create: engine_out NULL", vtsm_engine_create(storage, storage_len, &good, NULL),
           VTSM_FFI_NULL_POINTER);
    expect("create: config NULL", create_with(storage, storage_len, NULL), VTSM_FFI_NULL_POINTER);
    expect("create: storage NULL", create_with(NULL, storage_len, &good), VTSM_FFI_NULL_POINTER);
    expect("create: storage misaligned", create_with(storage + 1, storage_len - 1, &good),
           VTSM_FFI_MISALIGNED);
    expect("create: storage one byte short", create_with(storage, vtsm_storage_size(&good.params) - 1, &good),
           VTSM_CONFIG_CAPACITY_TOO_SMALL);
    expect("create: storage_len 0", create_with(storage, 0, &good), VTSM_CONFIG_CAPACITY_TOO_SMALL);

    c = good; c.io.read_window = NULL;
    expect("create: read_window NULL", create_with(storage, storage_len, &c), VTSM_FFI_NULL_POINTER);
    c = good; c.map = NULL; c.io.read_map = NULL;
    expect("create: no map and no read_map", create_with(storage, storage_len, &c), VTSM_FFI_NULL_POINTER);
    c = good; c.map = NULL; c.map_buffer = map_copy; c.map_buffer_len = map_len - 1;
    expect("create: map buffer one byte short", create_with(storage, storage_len, &c), VTSM_HAL_MAP_TOO_LARGE);
    c = good; c.map_len = 0;
    expect("create: map_len 0", create_with(storage, storage_len, &c), VTSM_HAL_MAP_TOO_LARGE);
    c = good; c.map_len = 100;
    expect("create: map truncated to 100 bytes", create_with(storage, storage_len, &c), VTSM_MAP_TRUNCATED);
    c = good; c.map = storage + 64; c.map_len = 4096;
    expect("create: map inside the storage", create_with(storage, storage_len, &c),
           VTSM_CONFIG_PARAM_OUT_OF_RANGE);

    memcpy(map_copy, good.map, map_len);
    map_copy[0] ^= 0xFF;
    c = good; c.map = map_copy;
    expect("create: map with a bad magic", create_with(storage, storage_len, &c), VTSM_MAP_BAD_MAGIC);
    map_copy[0] ^= 0xFF;
    map_copy[map_len / 2] ^= 0x01;
    expect("create: map with one bit flipped", create_with(storage, storage_len, &c), VTSM_MAP_CRC_MISMATCH);
    map_copy[map_len / 2] ^= 0x01;

    c = good; c.params.n_corr = 1;
    expect("create: n_corr 1", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.params.t0_m = NAN;
    expect("create: t0_m NaN", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.params.reuse = 7;
    expect("create: boolean 7", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.params.template_px = 1000;
    expect("create: template_px 1000", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.verify_recheck_map = 2;
    expect("create: verify flag 2", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.revisit_off = 2;
    expect("create: revisit_off 2", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.near_on = 255;
    expect("create: near_on 255", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.accuracy_sigma_t_m = 0.005f; /* rotation bound left 0 */
    expect("create: accuracy half given", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.accuracy_sigma_t_m = -0.005f; c.accuracy_sigma_r_deg = 0.1f;
    expect("create: accuracy negative", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.accuracy_sigma_t_m = NAN; c.accuracy_sigma_r_deg = 0.1f;
    expect("create: accuracy NaN", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.final_pairs = (uint16_t)(c.params.n_corr - 1u);
    expect("create: final_pairs below n_corr", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    c = good; c.final_pairs = 257u;
    expect("create: final_pairs above 256", create_with(storage, storage_len, &c), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    expect("params: unknown profile", vtsm_params_for_profile(42u, &c.params), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    expect("params: out NULL", vtsm_params_for_profile(VTSM_PROFILE_TEST, NULL), VTSM_FFI_NULL_POINTER);
    expect("storage size: params NULL is 0", vtsm_storage_size(NULL) == 0 ? VTSM_OK : 1, VTSM_OK);

    c = good; c.rig.fx = -1.0f;
    expect("create: negative focal length", create_with(storage, storage_len, &c), VTSM_STEREO_RIG_INVALID);
    c = good; c.rig.baseline_m = 0.0f;
    expect("create: zero baseline", create_with(storage, storage_len, &c), VTSM_STEREO_RIG_INVALID);
    c = good; c.prior.q[0] = 2.0f;
    expect("create: prior quaternion not unit", create_with(storage, storage_len, &c), VTSM_RELOC_PRIOR_INVALID);
    c = good; c.prior.t[1] = INFINITY;
    expect("create: prior translation infinite", create_with(storage, storage_len, &c), VTSM_HAL_PRIOR_INVALID);
    c = good; c.prior.covariance[0] = -1.0f;
    expect("create: negative prior variance", create_with(storage, storage_len, &c), VTSM_HAL_PRIOR_INVALID);
    c = good; c.prior.t_m = 5.0f; c.prior.r_deg = 1.0f;
    expect("create: stated uncertainty 5 m", create_with(storage, storage_len, &c), VTSM_HAL_PRIOR_INVALID);

    expect("run: engine NULL", vtsm_engine_run(NULL, NULL, &out), VTSM_FFI_NULL_POINTER);
    expect("run: outcome NULL", vtsm_engine_run((VtsmEngine *)(void *)blank, NULL, NULL), VTSM_FFI_NULL_POINTER);
    expect("run: storage that holds no engine", vtsm_engine_run((VtsmEngine *)(void *)blank, NULL, &out),
           VTSM_FFI_BAD_HANDLE);
    expect("run: misaligned handle", vtsm_engine_run((VtsmEngine *)(void *)(blank + 4), NULL, &out),
           VTSM_FFI_MISALIGNED);
    expect("run: outcome carries the code", out.failure, VTSM_FFI_MISALIGNED);

    /* A good engine, then bad runs. */
    expect("create: the scene", create_with(storage, storage_len, &good), VTSM_OK);
    (void)vtsm_engine_create(storage, storage_len, &good, &e);
    VtsmLimits zero_units = {0u, 10u, UINT64_MAX};
    expect("run: zero units per step", vtsm_engine_run(e, &zero_units, &out), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    dev.fail_windows = 1;
    expect("run: every window read fails", vtsm_engine_run(e, NULL, &out), VTSM_OK);
    expect("run: ... ends with", out.failure, VTSM_RELOC_FRAME_READ_FAILED);
    dev.fail_windows = 0;

    /* Step and outcome need a relocalization under way, and only one. */
    VtsmStepStatus st = VTSM_STEP_RUNNING;
    expect("step: not started", vtsm_engine_step(e, 4u, &st), VTSM_FFI_ENGINE_STATE);
    expect("outcome: not started", vtsm_engine_outcome(e, &out), VTSM_FFI_ENGINE_STATE);
    expect("outcome: ... carries the code", out.failure, VTSM_FFI_ENGINE_STATE);
    expect("step: storage that holds no engine", vtsm_engine_step((VtsmEngine *)(void *)blank, 4u, &st),
           VTSM_FFI_BAD_HANDLE);
    expect("start: engine NULL", vtsm_engine_start(NULL, NULL), VTSM_FFI_NULL_POINTER);
    expect("start: zero units per step", vtsm_engine_start(e, &zero_units), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    expect("start", vtsm_engine_start(e, NULL), VTSM_OK);
    expect("start: already under way", vtsm_engine_start(e, NULL), VTSM_FFI_ENGINE_STATE);
    expect("step: status NULL", vtsm_engine_step(e, 4u, NULL), VTSM_FFI_NULL_POINTER);
    expect("step: zero units", vtsm_engine_step(e, 0u, &st), VTSM_CONFIG_PARAM_OUT_OF_RANGE);
    expect("step: one unit", vtsm_engine_step(e, 1u, &st), VTSM_OK);
    expect("step: ... still running", st == VTSM_STEP_RUNNING ? VTSM_OK : 1, VTSM_OK);
    expect("outcome: stopped early", vtsm_engine_outcome(e, &out), VTSM_OK);
    expect("outcome: ... the anytime result", out.failure, VTSM_RELOC_BUDGET_EXHAUSTED);
    expect("step: finished", vtsm_engine_step(e, 4u, &st), VTSM_FFI_ENGINE_STATE);
    expect("outcome: taken already", vtsm_engine_outcome(e, &out), VTSM_FFI_ENGINE_STATE);

    /* The map read through the callback into a RAM buffer, one step. */
    c = good; c.map = NULL; c.map_buffer = map_copy; c.map_buffer_len = map_copy_len;
    expect("create: map through read_map", create_with(storage, storage_len, &c), VTSM_OK);
    (void)vtsm_engine_create(storage, storage_len, &c, &e);
    VtsmLimits one_step = {1u, 1u, UINT64_MAX};
    expect("run: read_map path, one step", vtsm_engine_run(e, &one_step, &out), VTSM_OK);
    expect("run: ... ends with", out.failure, VTSM_RELOC_BUDGET_EXHAUSTED);
    dev.map_len = 10; /* the store now refuses reads past 10 bytes */
    expect("run: map store refuses the range", vtsm_engine_run(e, &one_step, &out),
           VTSM_HAL_STORAGE_READ);
    dev.map_len = map_len;

    expect("name: unknown code", strcmp(vtsm_failure_name(0xFFFFu), "UNKNOWN") == 0 ? VTSM_OK : 1, VTSM_OK);
    printf("bad input: %d wrong\n", failures);
    return failures;
}

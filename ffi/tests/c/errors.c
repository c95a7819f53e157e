/* Bad input from C, one check per class of status (ffi/tests/c_host.rs runs it): invalid
 * parameters name the parameter (the acceleration limits too), a joint at its limit and
 * non-finite input are rejected steps with the zero command, NULL and misaligned pointers,
 * storage that no init wrote and the other scalar type are statuses; the start call is the
 * first step, taken now, and a rejected start leaves the controller as it was. Prints "ok NAME" or "FAIL NAME: ..." per check and
 * "N passed, M failed" at the end; exits 1 if a check failed. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "companion.h"

static int passed, failed;

static void check(const char *name, int ok, const char *detail) {
    if (ok) {
        passed++;
        printf("ok %s\n", name);
    } else {
        failed++;
        printf("FAIL %s: %s\n", name, detail);
    }
}

static void expect_status(const char *name, CompanionStatus got, CompanionStatus want) {
    char detail[160];
    snprintf(detail, sizeof detail, "got %s, want %s", companion_status_name(got), companion_status_name(want));
    check(name, got == want, detail);
}

static int is_zero(const CompanionCommandF64 *c) {
    if (c->v != 0.0 || c->v_lat != 0.0 || c->omega != 0.0 || c->v_xi != 0.0) return 0;
    for (int j = 0; j < COMPANION_JOINTS; j++)
        if (c->joints[j] != 0.0) return 0;
    return 1;
}

static CompanionMeasurementF64 start(void) {
    CompanionMeasurementF64 m = {0};
    m.joints[1] = 0.35;
    m.target.x = 2.6;
    m.target.y = 1.0;
    m.target_velocity[1] = -0.157;
    return m;
}

static const CompanionCommandF64 garbage = {42, 42, 42, 42, {42, 42, 42}};

/* A rejected step: its status, and the zero command written over `garbage`. */
static void expect_rejected(const char *name, CompanionController *ctrl, double period, double delay,
                            const CompanionMeasurementF64 *m, CompanionStatus want) {
    CompanionCommandF64 c = garbage;
    expect_status(name, companion_f64_step(ctrl, period, delay, m, &c), want);
    check(name, is_zero(&c), "the command written is not the zero command");
}

/* An invalid parameter: its status and name. */
static void expect_param(const char *name, const CompanionParamsF64 *p, CompanionStatus want, const char *param,
                         int joint) {
    CompanionController ctrl;
    CompanionParamError e;
    expect_status(name, companion_f64_init(&ctrl, p, &e), want);
    char detail[160];
    snprintf(detail, sizeof detail, "error names '%s' joint %d, want '%s' joint %d", e.param, (int)e.joint, param,
             joint);
    check(name, e.status == (int32_t)want && strcmp(e.param, param) == 0 && e.joint == joint, detail);
    /* A failed init leaves the storage not initialised. */
    CompanionMeasurementF64 m = start();
    expect_rejected(name, &ctrl, 1e-3, 0.0, &m, COMPANION_STATUS_NOT_INITIALISED);
}

int main(void) {
    CompanionParamsF64 paper, p;
    expect_status("params_paper", companion_f64_params_paper(COMPANION_PLATFORM_UNICYCLE, COMPANION_RUN_A, &paper),
                  COMPANION_STATUS_OK);

    /* Parameters, field by field from the preset. */
    p = paper, p.gain[1] = -3.0;
    expect_param("param_not_positive", &p, COMPANION_STATUS_PARAM_NOT_POSITIVE, "gain", 1);
    p = paper, p.filter_sigma = NAN;
    expect_param("param_non_finite", &p, COMPANION_STATUS_PARAM_NON_FINITE, "filter_sigma", -1);
    p = paper, p.max_time_step = 0.5;
    expect_param("param_period_too_long", &p, COMPANION_STATUS_PARAM_PERIOD_TOO_LONG, "max_time_step", -1);
    p = paper, p.weight = COMPANION_WEIGHT_FILTERED;
    expect_param("param_decomposition51", &p, COMPANION_STATUS_PARAM_DECOMPOSITION51_NEEDS_PSI_ONE,
                 "precompensation", -1);
    p = paper, p.joint_lower[2] = 5.0;
    expect_param("param_empty_interval", &p, COMPANION_STATUS_PARAM_EMPTY_INTERVAL, "joint_limits.lower", 2);
    p = paper, p.weight = 17;
    expect_param("param_bad_enum", &p, COMPANION_STATUS_BAD_ENUM, "weight", -1);
    p = paper, p.platform = COMPANION_PLATFORM_CAR, p.car_eta[0] = 1.0, p.car_eta[1] = 1.0, p.car_eta[2] = 1.0;
    expect_param("param_transversality", &p, COMPANION_STATUS_PARAM_TRANSVERSALITY, "eta", -1);
    p = paper, p.arm_l_e = -0.15;
    expect_param("param_geometry", &p, COMPANION_STATUS_PARAM_GEOMETRY, "l_e", -1);
    p = paper, p.acceleration_limits.forward = 0.0;
    expect_param("param_acceleration_forward", &p, COMPANION_STATUS_PARAM_NOT_POSITIVE, "acceleration_limits.forward",
                 -1);
    p = paper, p.acceleration_limits.joints[2] = NAN;
    expect_param("param_acceleration_joint", &p, COMPANION_STATUS_PARAM_NON_FINITE, "acceleration_limits.joints", 2);
    {
        CompanionController ctrl;
        CompanionParamError e;
        expect_status("init_paper_bad_enum", companion_f64_init_paper(&ctrl, 7, COMPANION_RUN_A, &e),
                      COMPANION_STATUS_BAD_ENUM);
        check("init_paper_bad_enum", strcmp(e.param, "platform") == 0, e.param);
    }

    /* Steps. */
    static CompanionController ctrl;
    expect_status("init", companion_f64_init(&ctrl, &paper, NULL), COMPANION_STATUS_OK);
    CompanionMeasurementF64 m = start(), bad;
    bad = m, bad.joints[1] = 0.0; /* q2 at its lower limit 0 */
    expect_rejected("step_joint_at_limit", &ctrl, 1e-3, 0.0, &bad, COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q2);
    bad = m, bad.joints[2] = 100.0;
    expect_rejected("step_joint_beyond_limit", &ctrl, 1e-3, 0.0, &bad, COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q3);
    bad = m, bad.base.theta = NAN;
    expect_rejected("step_non_finite_base", &ctrl, 1e-3, 0.0, &bad, COMPANION_STATUS_STEP_NON_FINITE_BASE_POSE);
    bad = m, bad.t = INFINITY;
    expect_rejected("step_non_finite_time", &ctrl, 1e-3, 0.0, &bad, COMPANION_STATUS_STEP_NON_FINITE_TIME);
    bad = m, bad.target.y = NAN;
    expect_rejected("step_non_finite_target", &ctrl, 1e-3, 0.0, &bad, COMPANION_STATUS_STEP_NON_FINITE_TARGET_POSE);
    expect_rejected("step_nan_period", &ctrl, NAN, 0.0, &m, COMPANION_STATUS_STEP_BAD_TIME_STEP);
    expect_rejected("step_zero_period", &ctrl, 0.0, 0.0, &m, COMPANION_STATUS_STEP_BAD_TIME_STEP);
    expect_rejected("step_long_period", &ctrl, 0.02, 0.0, &m, COMPANION_STATUS_STEP_BAD_TIME_STEP);
    expect_rejected("step_negative_delay", &ctrl, 1e-3, -1e-3, &m, COMPANION_STATUS_STEP_BAD_DELAY);

    /* A rejected step leaves the state as it was: the next valid step is a fresh
     * controller's first step. */
    {
        static CompanionController fresh;
        CompanionCommandF64 a, b;
        companion_f64_init(&fresh, &paper, NULL);
        expect_status("after_rejections", companion_f64_step(&ctrl, 1e-3, 0.0, &m, &a), COMPANION_STATUS_OK);
        companion_f64_step(&fresh, 1e-3, 0.0, &m, &b);
        check("after_rejections", memcmp(&a, &b, sizeof a) == 0 && !is_zero(&a),
              "the step after rejected ones differs from a fresh controller's first step");
        /* The storage is a plain value: a copy steps like the original. */
        static CompanionController copy;
        memcpy(&copy, &ctrl, sizeof ctrl);
        m.t = 1e-3;
        companion_f64_step(&ctrl, 1e-3, 0.0, &m, &a);
        companion_f64_step(&copy, 1e-3, 0.0, &m, &b);
        check("copy", memcmp(&a, &b, sizeof a) == 0, "a memcpy'd controller steps differently");
    }

    /* The start call: on a fresh controller the same command as its first step; a rejected
     * start writes the zero command and leaves the controller as it was; with acceleration
     * limits the first command is within a h of rest. */
    {
        static CompanionController a, b;
        CompanionCommandF64 ca, cb = garbage;
        CompanionMeasurementF64 m0 = start(), nan = start();
        companion_f64_init(&a, &paper, NULL);
        companion_f64_init(&b, &paper, NULL);
        nan.target_velocity[0] = NAN;
        expect_status("start_rejected", companion_f64_start(&b, 1e-3, 0.0, &nan, &cb),
                      COMPANION_STATUS_STEP_NON_FINITE_TARGET_VELOCITY);
        check("start_rejected", is_zero(&cb), "the command written is not the zero command");
        companion_f64_step(&a, 1e-3, 0.0, &m0, &ca);
        expect_status("start", companion_f64_start(&b, 1e-3, 0.0, &m0, &cb), COMPANION_STATUS_OK);
        check("start", memcmp(&ca, &cb, sizeof ca) == 0 && !is_zero(&ca),
              "the start call differs from a fresh controller's first step");
        p = paper, p.acceleration_limits.forward = 1.0, p.acceleration_limits.angular = 2.0;
        companion_f64_init(&a, &p, NULL);
        expect_status("start_limited", companion_f64_start(&a, 1e-3, 0.0, &m0, &ca), COMPANION_STATUS_OK);
        check("start_limited", fabs(ca.v) <= 1e-3 * (1 + 1e-12) && fabs(ca.omega) <= 2e-3 * (1 + 1e-12) &&
                                   (fabs(ca.v) > 0.999e-3 || fabs(ca.omega) > 1.999e-3),
              "the first command is not on the acceleration limits from rest");
    }

    /* The call itself. */
    {
        CompanionCommandF64 c = garbage;
        expect_status("null_controller", companion_f64_step(NULL, 1e-3, 0.0, &m, &c), COMPANION_STATUS_NULL_POINTER);
        check("null_controller", is_zero(&c), "the command written is not the zero command");
        c = garbage;
        expect_status("null_measurement", companion_f64_step(&ctrl, 1e-3, 0.0, NULL, &c),
                      COMPANION_STATUS_NULL_POINTER);
        check("null_measurement", is_zero(&c), "the command written is not the zero command");
        expect_status("null_command", companion_f64_step(&ctrl, 1e-3, 0.0, &m, NULL), COMPANION_STATUS_NULL_POINTER);
        expect_status("null_params", companion_f64_init(&ctrl, NULL, NULL), COMPANION_STATUS_NULL_POINTER);
        expect_status("null_params_out", companion_f64_params_paper(0, 0, NULL), COMPANION_STATUS_NULL_POINTER);
        static uint64_t words[COMPANION_CONTROLLER_WORDS + 1];
        CompanionController *odd = (CompanionController *)((char *)words + 4);
        expect_status("misaligned_storage", companion_f64_init_paper(odd, 0, 0, NULL), COMPANION_STATUS_MISALIGNED);
        static CompanionController never;
        c = garbage;
        expect_status("not_initialised", companion_f64_step(&never, 1e-3, 0.0, &m, &c),
                      COMPANION_STATUS_NOT_INITIALISED);
        check("not_initialised", is_zero(&c), "the command written is not the zero command");
        companion_f64_init(&ctrl, &paper, NULL); /* (the NULL-params init above cleared it) */
        CompanionMeasurementF32 m32 = {0};
        CompanionCommandF32 c32;
        expect_status("wrong_scalar", companion_f32_step(&ctrl, 1e-3f, 0.0f, &m32, &c32),
                      COMPANION_STATUS_WRONG_SCALAR);
    }
    check("status_name", strcmp(companion_status_name(221), "COMPANION_STATUS_STEP_JOINT_AT_LIMIT_Q2") == 0,
          companion_status_name(221));
    check("status_name_unknown", strcmp(companion_status_name(-7), "COMPANION_STATUS_UNKNOWN") == 0,
          companion_status_name(-7));
    check("storage_size", sizeof(CompanionController) == COMPANION_CONTROLLER_SIZE &&
                              _Alignof(CompanionController) == COMPANION_CONTROLLER_ALIGN,
          "sizeof/alignof CompanionController differ from the header's constants");

    printf("%d passed, %d failed\n", passed, failed);
    return failed == 0 ? 0 : 1;
}

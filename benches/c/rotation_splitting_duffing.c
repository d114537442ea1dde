/*
 * The Duffing peer of `ecr bench`, written for speed: kick-rotate-kick splitting with the exact
 * harmonic flow, composed to order 2, 4, 6 or 8 (the composition's sub-steps gamma_1..gamma_s
 * are the caller's: Strang, Yoshida, Kahan-Li s = 9 and 15), for
 *
 *     q'' + W q = c3 q^3        (Duffing: W = w^2 + k^2, c3 = 2 k^2),
 *
 * the same method as `ecr::baselines::splitting::RotationSplitting` (bench series "Rot{p}"),
 * rounded differently. `ecr bench` compiles this file with the `cc` crate (the `cli` feature's
 * build script) and calls it once over [0, T] (series "Rot{p} C" and "Rot{p} C plain").
 *
 * What makes it fast (all of it set up once per step size, in ecr_rot_duffing_init):
 * - Adjacent half-kicks merged, also across steps: a step is s stages of kick + rotation, the
 *   state between calls is kept half a kick behind p (enter/leave convert).
 * - The kick folded into the rotation (the force c3 q^3 is a function of q alone):
 *       q' = c q + (sin t/w) p + (a sin t/w) q^3,   p' = -w sin t q + c p + (a c) q^3,
 *   so a stage's dependency chain is q^2 and (a sin t/w) q in parallel, their product, and
 *   the sums: 3 dependent floating-point operations (plain form) instead of the 5 or 6 of a
 *   kick followed by a rotation.
 * - Two forms of the rotation:
 *   "plain": the 2 x 2 product with c = cos t rounded. Its determinant c^2 + sin^2 t is 1 only
 *     to about an ulp, the same every step: the amplitude drifts (Duffing w = 20, T = 1000:
 *     errors stall at 5e-10 to 3e-9 from h = 1/128 on).
 *   "accurate" (default): c = 1 + (c - 1), c - 1 = -2 sin^2(t/2) stored exactly to an ulp of
 *     itself and q added last, as the library's RotationSplitting does: no drift (errors stall
 *     at 3e-11 to 7e-11), one more operation in the chain; where the processor has fused
 *     multiply-add (chosen at run time on x86 with GCC or Clang) the chain is
 *     fma(a sin t/w q, q^2, fma(c - 1, q, q) + (sin t/w) p): by the published latencies 11
 *     cycles instead of 12 on AMD Zen 3 (measured below: 8 % faster), 12 instead of 16 on
 *     recent Intel cores (plain: 9 and 12).
 * Compile with -ffp-contract=off (as the build script does), so that the compiler does not
 * contract the sums into fused multiply-adds that lengthen the chain or change the bits.
 *
 * Measured 2026-11-27 on this project's machine (AMD EPYC, Zen 3, 2 cores under KVM, shared with
 * other builds), gcc 12.2, w = 20, k = 0.07, T = 1000, h = 1/32 (32 000 steps), order 8, the
 * loop alone with its set-up, fastest of 40 calls:
 *     gcc -O2 -ffp-contract=off -DECR_ROT_MAIN -o rot8 benches/c/rotation_splitting_duffing.c -lm
 *     ./rot8 32000 1000 FORM 40
 *   accurate (fma)     1.92 ms   global error 6.3e-10   (form accurate-fma, the default here)
 *   accurate (no fma)  2.08 ms   global error 6.3e-10   (form accurate-nofma)
 *   plain              1.56 ms   global error 8.1e-10   (form plain; 2e-10 of it is the drift)
 * and, timed the same way in the same hour: a kick followed by a plain rotation, coefficients
 * precomputed (what the plain 2 x 2 product gives without folding the kick in) 2.71 ms; the
 * previous version of this file (kick coefficients recomputed every stage, rotation as the
 * identity plus an increment; see its git history) 3.61 ms. `ecr bench` times the same calls
 * from Rust (series "Rot8 C", "Rot8 C plain"), and in its summary against the library's
 * RotationSplitting at equal h.
 * The program prints the loop's time apart from the process's: `./rot8 1 0.1` (one step)
 * takes about 20 us of loop, the rest of its process time is start-up.
 */
#if defined(ECR_ROT_MAIN) && !defined(_POSIX_C_SOURCE)
#define _POSIX_C_SOURCE 199309L /* clock_gettime */
#endif
#include <math.h>
#include <stddef.h>

/* Most sub-steps of a composition (Kahan-Li order 8). */
#define ECR_ROT_MAX_STAGES 15

/* The forms of a stage (ecr_rot_duffing::form). */
enum { ECR_ROT_ACCURATE = 0, ECR_ROT_ACCURATE_FMA = 1, ECR_ROT_PLAIN = 2 };
/* ecr_rot_duffing_init's `form`: the accurate form, with fma where the processor has it. */
#define ECR_ROT_FASTEST_ACCURATE (-1)

/* One step size's coefficients. Stage i: the kick merged with the one before it, then the
 * rotation by gamma_i h. */
struct ecr_rot_duffing {
    int stages;
    int form;
    /* c - 1 (accurate forms) or c (plain) of each stage's rotation angle. */
    double lin[ECR_ROT_MAX_STAGES];
    /* sin t / w (t for w = 0). */
    double qp[ECR_ROT_MAX_STAGES];
    /* -w sin t. */
    double pq[ECR_ROT_MAX_STAGES];
    /* The kick a (c3 h times the merged half sub-steps) times sin t / w, and times c. */
    double kq[ECR_ROT_MAX_STAGES];
    double kp[ECR_ROT_MAX_STAGES];
    /* The last half-kick, c3 h gamma_s / 2: the state between calls is p - last q^3. */
    double last;
};

/* Kahan & Li (1997) "s15odr8" as printed in Hairer-Lubich-Wanner (26 digits): the same table
 * as `ecr::baselines::splitting::KAHAN_LI8` (a test compares them bit for bit). */
const double ecr_rot_kahan_li8[15] = {
    0.74167036435061295344822780,  -0.40910082580003159399730010, 0.19075471029623837995387626,
    -0.57386247111608226665638773, 0.29906418130365592384446354,  0.33462491824529818378495798,
    0.31529309239676659663205666,  -0.79688793935291635401978884, 0.31529309239676659663205666,
    0.33462491824529818378495798,  0.29906418130365592384446354,  -0.57386247111608226665638773,
    0.19075471029623837995387626,  -0.40910082580003159399730010, 0.74167036435061295344822780};

size_t ecr_rot_duffing_size(void) { return sizeof(struct ecr_rot_duffing); }

#if defined(__FP_FAST_FMA)
#define ECR_ROT_HAS_FMA 1 /* fma() is one instruction on every processor of this target */
#elif (defined(__GNUC__) || defined(__clang__)) && (defined(__x86_64__) || defined(__i386__))
#define ECR_ROT_DISPATCH 1 /* fma() is one instruction where the processor has it */
#endif

static int fma_available(void) {
#if defined(ECR_ROT_HAS_FMA)
    return 1;
#elif defined(ECR_ROT_DISPATCH)
    __builtin_cpu_init();
    return __builtin_cpu_supports("fma");
#else
    return 0;
#endif
}

/* Sets up `m` for step size h, sub-steps gamma[0..s) and the given form (one of the enum, or
 * ECR_ROT_FASTEST_ACCURATE). Returns 0, or -1 for s outside 1..15, h not positive, W < 0,
 * anything not finite or a form that this processor cannot run (then `m` is unusable). */
int ecr_rot_duffing_init(struct ecr_rot_duffing *m, double stiffness, double cubic, double h,
                         const double *gamma, int s, int form) {
    if (s < 1 || s > ECR_ROT_MAX_STAGES || !(h > 0.0) || !isfinite(h) || !(stiffness >= 0.0) ||
        !isfinite(stiffness) || !isfinite(cubic))
        return -1;
    if (form == ECR_ROT_FASTEST_ACCURATE)
        form = fma_available() ? ECR_ROT_ACCURATE_FMA : ECR_ROT_ACCURATE;
    if (!(form == ECR_ROT_ACCURATE || form == ECR_ROT_PLAIN ||
          (form == ECR_ROT_ACCURATE_FMA && fma_available())))
        return -1;
    const int plain = form == ECR_ROT_PLAIN;
    const double w = sqrt(stiffness);
    m->stages = s;
    m->form = form;
    for (int i = 0; i < s; i++) {
        if (!isfinite(gamma[i]))
            return -1;
        /* The kick before rotation i: half of sub-step i and half of the one before it (for
         * i = 0 the previous step's last). */
        const double a = cubic * h * (0.5 * (gamma[i] + gamma[i == 0 ? s - 1 : i - 1]));
        const double tau = gamma[i] * h;
        double cm1, c, qp, pq;
        if (w == 0.0) {
            cm1 = 0.0, c = 1.0, qp = tau, pq = 0.0;
        } else {
            const double sn = sin(tau * w), half = sin(0.5 * tau * w);
            cm1 = -2.0 * half * half; /* cos t - 1 without cancellation */
            c = plain ? cos(tau * w) : 1.0 + cm1;
            qp = sn / w;
            pq = -w * sn;
        }
        m->lin[i] = plain ? c : cm1;
        m->qp[i] = qp;
        m->pq[i] = pq;
        m->kq[i] = qp * a;
        m->kp[i] = c * a;
    }
    m->last = cubic * h * (0.5 * gamma[s - 1]);
    return 0;
}

/* (q, p) -> the state between calls, (q, p - last q^3). */
void ecr_rot_duffing_enter(const struct ecr_rot_duffing *m, double *y) {
    const double q = y[0];
    y[1] -= (m->last * q) * (q * q);
}

/* The state between calls -> (q, p) in out (y is left as it is). */
void ecr_rot_duffing_leave(const struct ecr_rot_duffing *m, const double *y, double *out) {
    const double q = y[0];
    out[0] = q;
    out[1] = y[1] + (m->last * q) * (q * q);
}

/* n steps of the state between calls. The stage count is a constant in each instance, so that
 * the compiler unrolls the stages and keeps their coefficients at hand. */
#define ECR_ROT_LOOP(NAME, STAGE)                                                                \
    static inline void NAME(const struct ecr_rot_duffing *m, double *y, long n, const int s) {  \
        double q = y[0], p = y[1];                                                               \
        for (long step = 0; step < n; step++) {                                                  \
            for (int i = 0; i < s; i++) {                                                        \
                const double q2 = q * q, q0 = q, p0 = p;                                         \
                STAGE                                                                            \
            }                                                                                    \
        }                                                                                        \
        y[0] = q;                                                                                \
        y[1] = p;                                                                                \
    }

ECR_ROT_LOOP(steps_plain, {
    q = (m->lin[i] * q0 + m->qp[i] * p0) + (m->kq[i] * q0) * q2;
    p = (m->pq[i] * q0 + m->lin[i] * p0) + (m->kp[i] * q0) * q2;
})

ECR_ROT_LOOP(steps_accurate, {
    q = q0 + ((m->lin[i] * q0 + m->qp[i] * p0) + (m->kq[i] * q0) * q2);
    p = p0 + ((m->pq[i] * q0 + m->lin[i] * p0) + (m->kp[i] * q0) * q2);
})

#if defined(ECR_ROT_HAS_FMA) || defined(ECR_ROT_DISPATCH)
#if defined(ECR_ROT_DISPATCH)
#define ECR_ROT_FMA_TARGET __attribute__((target("fma")))
#else
#define ECR_ROT_FMA_TARGET
#endif
#define ECR_ROT_FMA_STAGE                                                                        \
    {                                                                                            \
        q = fma(m->kq[i] * q0, q2, fma(m->lin[i], q0, q0) + m->qp[i] * p0);                      \
        p = fma(m->kp[i] * q0, q2, fma(m->lin[i], p0, p0) + m->pq[i] * q0);                      \
    }
ECR_ROT_FMA_TARGET ECR_ROT_LOOP(steps_fma_inline, ECR_ROT_FMA_STAGE)
static ECR_ROT_FMA_TARGET void steps_fma(const struct ecr_rot_duffing *m, double *y, long n) {
    switch (m->stages) {
    case 1: steps_fma_inline(m, y, n, 1); break;
    case 3: steps_fma_inline(m, y, n, 3); break;
    case 9: steps_fma_inline(m, y, n, 9); break;
    case 15: steps_fma_inline(m, y, n, 15); break;
    default: steps_fma_inline(m, y, n, m->stages);
    }
}
#endif

/* n >= 0 steps of the state between calls (see ecr_rot_duffing_enter). */
void ecr_rot_duffing_steps(const struct ecr_rot_duffing *m, double *y, long n) {
#define ECR_ROT_BY_STAGES(F)                                                                     \
    switch (m->stages) {                                                                         \
    case 1: F(m, y, n, 1); break;                                                                \
    case 3: F(m, y, n, 3); break;                                                                \
    case 9: F(m, y, n, 9); break;                                                                \
    case 15: F(m, y, n, 15); break;                                                              \
    default: F(m, y, n, m->stages);                                                              \
    }
    switch (m->form) {
    case ECR_ROT_PLAIN: ECR_ROT_BY_STAGES(steps_plain); break;
#if defined(ECR_ROT_HAS_FMA) || defined(ECR_ROT_DISPATCH)
    case ECR_ROT_ACCURATE_FMA: steps_fma(m, y, n); break;
#endif
    default: ECR_ROT_BY_STAGES(steps_accurate);
    }
#undef ECR_ROT_BY_STAGES
}

#ifdef ECR_ROT_MAIN
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Duffing w = 20, k = 0.07, (q, p)(0) = (0, w): N steps of order 8 over [0, T], R times. */
int main(int argc, char **argv) {
    static const char *const names[] = {"accurate-nofma", "accurate-fma", "plain"};
    int form = ECR_ROT_FASTEST_ACCURATE;
    if (argc >= 4 && strcmp(argv[3], "accurate") != 0) {
        form = -2;
        for (int i = 0; i < 3; i++)
            if (strcmp(argv[3], names[i]) == 0)
                form = i;
    }
    const long n = argc >= 3 ? atol(argv[1]) : 0;
    const double t = argc >= 3 ? atof(argv[2]) : 0.0;
    const long repeats = argc == 5 ? atol(argv[4]) : 1;
    if (argc < 3 || argc > 5 || form == -2 || n <= 0 || !(t > 0.0) || repeats <= 0) {
        fprintf(stderr,
                "usage: %s N T [accurate|accurate-nofma|accurate-fma|plain] [R]\n"
                "  N > 0 steps of h = T/N over [0, T], T > 0; the loop R > 0 times\n",
                argv[0]);
        return 2;
    }
    const double w = 20.0, k = 0.07;
    double best = INFINITY, out[2] = {0.0, 0.0};
    struct ecr_rot_duffing m;
    for (long r = 0; r < repeats; r++) {
        const double t0 = now();
        if (ecr_rot_duffing_init(&m, w * w + k * k, 2.0 * k * k, t / (double)n, ecr_rot_kahan_li8,
                                 15, form) != 0) {
            fprintf(stderr, "this processor cannot run the form %s\n", argv[3]);
            return 2;
        }
        double y[2] = {0.0, w};
        ecr_rot_duffing_enter(&m, y);
        ecr_rot_duffing_steps(&m, y, n);
        ecr_rot_duffing_leave(&m, y, out);
        const double seconds = now() - t0;
        if (seconds < best)
            best = seconds;
    }
    printf("{\"q\": %.17g, \"p\": %.17g, \"form\": \"%s\", \"loop_seconds\": %.3e, \"repeats\": "
           "%ld}\n",
           out[0], out[1], names[m.form], best, repeats);
    return 0;
}
#endif

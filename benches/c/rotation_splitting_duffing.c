/*
 * The Duffing peer of `ecr bench` written as a C programmer writes it: kick-rotate-kick with
 * the exact harmonic flow, composed to order 8 (Kahan-Li, 15 stages), scalars in registers,
 * the rotation as the identity plus an increment (cos - 1 = -2 sin^2(theta/2)), FSAL force.
 * The same method and coefficients as `ecr::baselines::splitting::RotationSplitting` with
 * order 8 (the series "Rot8 (Kahan-Li)"), for checking that the library's peer is as fast as
 * an independent implementation.
 *
 * Duffing: q'' + (w^2 + k^2) q = 2 k^2 q^3, w = 20, k = 0.07, (q, p)(0) = (0, w).
 *
 *   gcc -O2 -o rot8 benches/c/rotation_splitting_duffing.c -lm
 *   ./rot8 N T        # N steps of h = T/N over [0, T]; prints the final (q, p)
 *
 * Measured 2026-11-26 (Intel Xeon 2.5 GHz): N = 32000, T = 1000 (h = 0.03125) takes 6.1 ms
 * of process CPU (of which about 0.5 ms is the process's start); `ecr bench`'s Rot8 at the
 * same h 5.5 ms in the same hour. One step (N = 1, T = 0.1): 0.72 ms, the start-up reference
 * of the README's "Speed" section.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static const double G[15] = {
    0.74167036435061295344822780,  -0.40910082580003159399730010, 0.19075471029623837995387626,
    -0.57386247111608226665638773, 0.29906418130365592384446354,  0.33462491824529818378495798,
    0.31529309239676659663205666,  -0.79688793935291635401978884, 0.31529309239676659663205666,
    0.33462491824529818378495798,  0.29906418130365592384446354,  -0.57386247111608226665638773,
    0.19075471029623837995387626,  -0.40910082580003159399730010, 0.74167036435061295344822780};

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s N T\n", argv[0]);
        return 2;
    }
    const int n = atoi(argv[1]);
    const double t = atof(argv[2]);
    if (n <= 0 || !(t > 0.0)) {
        fprintf(stderr, "N must be positive and T > 0\n");
        return 2;
    }
    const double om = 20.0, k = 0.07, h = t / n;
    const double w = sqrt(om * om + k * k), k2 = 2.0 * k * k;
    double c[15], s1[15], s2[15];
    for (int i = 0; i < 15; i++) {
        const double th = G[i] * h * w, half = sin(0.5 * th), sn = sin(th);
        c[i] = -2.0 * half * half;
        s1[i] = sn / w;
        s2[i] = -w * sn;
    }
    double q = 0.0, p = om, f = k2 * q * q * q;
    for (int step = 0; step < n; step++) {
        double cc = 0.5 * G[0];
        for (int i = 0; i < 15; i++) {
            p += cc * h * f;
            const double q0 = q, p0 = p;
            q = q0 + (c[i] * q0 + s1[i] * p0);
            p = p0 + (s2[i] * q0 + c[i] * p0);
            f = k2 * q * q * q;
            cc = 0.5 * (G[i] + (i < 14 ? G[i + 1] : 0.0));
        }
        p += cc * h * f;
    }
    printf("{\"q\": %.17g, \"p\": %.17g}\n", q, p);
    return 0;
}

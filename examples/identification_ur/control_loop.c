/* A 1 kHz feedforward loop on the identified UR-type arm, calling the exported inverse dynamics.
 *
 * Build (identify_ur.py does it): export the identified model with
 *     casmbd export identified.toml --c c --functions inverse_dynamics --prefix ur5
 * then
 *     cc -std=c99 -O2 -Ic control_loop.c c/ur5.c c/ur5_model.c -lm -o control_loop
 * Run:
 *     ./control_loop trajectory.txt reference.csv
 *
 * trajectory.txt: the desired motion as a Fourier series (casmbd.ocp.excitation):
 *     T n L
 *     q0[0] ... q0[n-1]
 *     a[0][0] ... a[0][L-1] a[1][0] ...      (row-major, n x L)
 *     b[0][0] ...                            (row-major, n x L)
 *   q_i(t) = q0_i + sum_l a_il/(w l) sin(w l t) - b_il/(w l) cos(w l t), w = 2 pi / T.
 * reference.csv: one line per control step, the n torques of the Python API
 *   (casmbd.compile(identified).inverse_dynamics at the same instants).
 *
 * Each step k (t = k / 1000 s) evaluates the desired q, v, a, forms the computed-torque
 * acceleration a_cmd = a_d + Kp (q_d - q) + Kd (v_d - v) -- with the measured state taken equal
 * to the desired one here (there is no plant in this example, so the feedback terms vanish and
 * tau is the pure feedforward) -- and calls ur5_inverse_dynamics(q, v, a_cmd).  It prints
 * "steps=N max_torque_difference=X max_torque=Y" (N m): the largest |tau_C - tau_Python|.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "ur5.h"

#define NMAX 16
#define LMAX 16
#define RATE 1000.0

static const double KP = 400.0, KD = 40.0; /* 1/s^2, 1/s: a critically damped error, 20 rad/s */

static int read_numbers(FILE *f, double *x, int count) {
    for (int i = 0; i < count; ++i)
        if (fscanf(f, "%lf", &x[i]) != 1) return -1;
    return 0;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s trajectory.txt reference.csv\n", argv[0]);
        return 2;
    }
    FILE *ft = fopen(argv[1], "r");
    if (!ft) { perror(argv[1]); return 2; }
    double period;
    int n, L;
    if (fscanf(ft, "%lf %d %d", &period, &n, &L) != 3 || n != ur5_NV || L < 1 || L > LMAX
        || !(period > 0.0)) {
        fprintf(stderr, "%s: bad header (expected T n=%d L)\n", argv[1], ur5_NV);
        return 2;
    }
    double q0[NMAX], a[NMAX * LMAX], b[NMAX * LMAX];
    if (read_numbers(ft, q0, n) || read_numbers(ft, a, n * L) || read_numbers(ft, b, n * L)) {
        fprintf(stderr, "%s: too few coefficients\n", argv[1]);
        return 2;
    }
    fclose(ft);
    FILE *fr = fopen(argv[2], "r");
    if (!fr) { perror(argv[2]); return 2; }

    ur5_work work; /* caller-owned work space: no allocation in the loop */
    const double w = 2.0 * 3.14159265358979323846 / period;
    double q[NMAX], v[NMAX], acc[NMAX], qd[NMAX], vd[NMAX], ad[NMAX], tau[NMAX], ref[NMAX];
    double worst = 0.0, largest = 0.0;
    long steps = 0;
    for (;; ++steps) {
        if (read_numbers(fr, ref, n)) break; /* one reference line per step; EOF ends */
        const double t = steps / RATE;
        for (int i = 0; i < n; ++i) {
            qd[i] = q0[i];
            vd[i] = 0.0;
            ad[i] = 0.0;
            for (int l = 1; l <= L; ++l) {
                const double s = sin(w * l * t), c = cos(w * l * t);
                const double ai = a[i * L + l - 1], bi = b[i * L + l - 1];
                qd[i] += ai / (w * l) * s - bi / (w * l) * c;
                vd[i] += ai * c + bi * s;
                ad[i] += -ai * w * l * s + bi * w * l * c;
            }
            q[i] = qd[i]; /* the measured state (here: on the desired trajectory) */
            v[i] = vd[i];
            acc[i] = ad[i] + KP * (qd[i] - q[i]) + KD * (vd[i] - v[i]);
        }
        const int rc = ur5_inverse_dynamics(q, v, acc, tau, &work);
        if (rc != ur5_OK) {
            fprintf(stderr, "step %ld: %s\n", steps, ur5_strerror(rc));
            return 1;
        }
        for (int i = 0; i < n; ++i) {
            const double d = fabs(tau[i] - ref[i]);
            if (d > worst) worst = d;
            if (fabs(tau[i]) > largest) largest = fabs(tau[i]);
        }
    }
    fclose(fr);
    printf("steps=%ld max_torque_difference=%.3e max_torque=%.6g\n", steps, worst, largest);
    return steps > 0 ? 0 : 1;
}

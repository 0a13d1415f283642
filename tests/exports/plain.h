/* magyro calibration, exported for other programs (magyro export --format c).
 * source: given.json
 * magnetometer unit: uT
 *   gyro, frame b:  w_b = K_g y + eps_b   (rad/s, gyro frame; the bias is ADDED: not y - b)
 *   gyro, frame m:  w_m = K y + eps       (rad/s, magnetometer frame; K = C_b_m K_g, eps = C_b_m eps_b)
 *   magnetometer:   m_m = R (y_m - h)     (unitless, unit norm; h in the magnetometer's unit)
 *   y: raw gyro in rad/s; y_m: raw magnetometer in its unit; matrices are row-major, [row][column]
 * C99, no allocation; include it in one or more .c files. */
#ifndef MAGYRO_CALIBRATION_H
#define MAGYRO_CALIBRATION_H

/* gyro scale and non-orthogonality, upper triangular */
static const double magyro_K_g[3][3] = {
    {1.002, 0.0012, -0.0005},
    {0.0, 0.9981, 0.0007},
    {0.0, 0.0, 1.0011}
};
/* eps_b, rad/s, ADDED: w_b = K_g y + eps_b */
static const double magyro_bias_rad_s[3] = {0.01, -0.02, 0.005};
/* C_b_m K_g */
static const double magyro_K[3][3] = {
    {1.0017176827931233, -0.02152798189765012, -0.007224942041295358},
    {0.022732154259862646, 0.9977939218049772, -0.011697417253688112},
    {0.006995222818557476, 0.012201868891992622, 1.0010059543489704}
};
/* eps = C_b_m eps_b, rad/s */
static const double magyro_eps_rad_s[3] = {0.010419091776724603, -0.019828314610048532, 0.0048249835515912};
/* gyro frame to magnetometer frame */
static const double magyro_C_b_m[3][3] = {
    {0.9997182463005223, -0.0227709085193976, -0.0067017713337144316},
    {0.022686780698465716, 0.9996660631881966, -0.012372230653851379},
    {0.0069812602979615525, 0.012216703115554622, 0.9999010021845355}
};
/* magnetometer soft iron, 1/uT */
static const double magyro_R[3][3] = {
    {0.0222, 0.0003, -0.0002},
    {0.0, 0.0224, 0.0001},
    {0.0, 0.0, 0.0221}
};
/* magnetometer hard iron, uT */
static const double magyro_h[3] = {3.5, -12.25, 40.125};

/* w = M y + b for a 3x3 M and 3-vectors y, b */
static inline void magyro_affine3(const double M[3][3], const double y[3], const double b[3], double w[3])
{
    int i;
    for (i = 0; i < 3; ++i) {
        w[i] = M[i][0] * y[0] + M[i][1] * y[1] + M[i][2] * y[2] + b[i];
    }
}

/* calibrated rate in the gyro frame b: w = K_g y + eps_b (rad/s in, rad/s out) */
static inline void magyro_apply_gyro(const double y[3], double w[3])
{
    magyro_affine3(magyro_K_g, y, magyro_bias_rad_s, w);
}

/* calibrated rate in the magnetometer frame m: w = K y + eps (rad/s in, rad/s out) */
static inline void magyro_apply_gyro_m(const double y[3], double w[3])
{
    magyro_affine3(magyro_K, y, magyro_eps_rad_s, w);
}

/* calibrated field in the magnetometer frame: m = R (y_m - h), unit norm */
static inline void magyro_apply_mag(const double y_m[3], double m[3])
{
    const double d[3] = {y_m[0] - magyro_h[0], y_m[1] - magyro_h[1], y_m[2] - magyro_h[2]};
    const double zero[3] = {0.0, 0.0, 0.0};
    magyro_affine3(magyro_R, d, zero, m);
}

#endif /* MAGYRO_CALIBRATION_H */

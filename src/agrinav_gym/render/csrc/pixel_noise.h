/* Per-pixel standard normal draws from a counter (render/pixel_noise.py documents the design
 * and builds the tables; its numpy twin gives the same bits): pixel i's draw is a function of
 * the frame's key and i alone, so a band computes only the pixels it needs.
 */
#ifndef AGRINAV_PIXEL_NOISE_H
#define AGRINAV_PIXEL_NOISE_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#define PN_LAYERS 256
#define PN_GAMMA 0x9E3779B97F4A7C15ULL
#define PN_KEY2 0xD1B54A32D192ED03ULL
#define PN_SLOW_STRIDE_BITS 12

typedef struct {
    uint64_t key, key2;
    const double *x; /* PN_LAYERS + 1 layer edges, x[1] = r, x[PN_LAYERS] = 0 */
    const double *w; /* PN_LAYERS: x * 2^-53 */
    const double *f; /* PN_LAYERS + 1: exp(-x^2 / 2) */
} pnoise_t;

/* SplitMix64's output function */
static inline uint64_t pn_mix(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

/* output c of the SplitMix64 stream whose state is key */
static inline uint64_t pn_bits(uint64_t key, uint64_t c) {
    return pn_mix(key + (c + 1) * PN_GAMMA);
}

/* the tables as pixel_noise.TABLES lays them out */
static inline pnoise_t pn_init(const double *tables, uint64_t key) {
    pnoise_t p = {key, pn_mix(key ^ PN_KEY2), tables, tables + PN_LAYERS + 1,
                  tables + 2 * PN_LAYERS + 1};
    return p;
}

static inline double pn_unit_open(uint64_t b) {
    return (double)(int64_t)((b >> 11) + 1) * 0x1p-53;
}

/* the draws whose first bits u fell outside their layer's rectangle (about 1.5 %): the wedge's
 * test, the tail beyond r, and fresh bits from the second stream on a rejection */
static double pn_slow(const pnoise_t *p, uint64_t i, uint64_t u) {
    uint64_t c = i << PN_SLOW_STRIDE_BITS;
    for (;;) {
        int layer = (int)(u & 0xFF);
        double x = (double)(int64_t)(u >> 11) * p->w[layer];
        double sign = (u & 0x100) ? -1.0 : 1.0;
        if (x < p->x[layer + 1]) return sign * x;
        if (layer == 0) { /* loop in the tail: restarting would bias its mass */
            for (;;) {
                double a = -log(pn_unit_open(pn_bits(p->key2, c))) / p->x[1];
                double b = -log(pn_unit_open(pn_bits(p->key2, c + 1)));
                c += 2;
                if (b + b > a * a) return sign * (p->x[1] + a);
            }
        }
        double y = p->f[layer] + (double)(int64_t)(pn_bits(p->key2, c) >> 11) * 0x1p-53 *
                                     (p->f[layer + 1] - p->f[layer]);
        c++;
        if (y < exp(-0.5 * x * x)) return sign * x;
        u = pn_bits(p->key2, c++);
    }
}

/* -x where bit 8 of u is set: without a branch, which would miss half the time */
static inline double pn_sign(double x, uint64_t u) {
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    b ^= (u & 0x100) << 55;
    memcpy(&x, &b, sizeof b);
    return x;
}

/* pixel i's standard normal draw */
static inline double pn_normal(const pnoise_t *p, uint64_t i) {
    uint64_t u = pn_bits(p->key, i);
    int layer = (int)(u & 0xFF);
    double x = (double)(int64_t)(u >> 11) * p->w[layer];
    return x < p->x[layer + 1] ? pn_sign(x, u) : pn_slow(p, i, u);
}

#endif

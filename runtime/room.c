/*
 * room.c - image sources and the FDN of a box room.  The model, units and
 * real-time rules are in room.h.
 */
#include "room.h"

#include <assert.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "wdrt.h"

#define LN10 2.30258509299404568402
#define FLUSH 1e-30           /* below this a decaying value becomes 0 */
#define LINE_MIN 0.01         /* s: shortest base line length */
#define LINE_MAX 0.1          /* s: longest base line length (lines span an octave above it) */
#define MODAL_DENSITY 0.15    /* Jot: total delay >= 0.15 T60 for a smooth decay */

/* A first-order filter y = b0 x + z, z' = b1 x - a1 y (transposed direct form II). */
typedef struct shelf {
    double b0, b1, a1;
    double z; /* state */
} shelf;

struct room_fdn {
    double *line[ROOM_FDN_N]; /* delay lines, in the memory after this struct */
    int len[ROOM_FDN_N];      /* their lengths, samples: distinct primes */
    int pos[ROOM_FDN_N];      /* read-then-write index of each line */
    double *pre;              /* the pre-delay line */
    int npre;                 /* its length, samples (>= 1) */
    int prepos;               /* its read-then-write index */
    shelf loss[ROOM_FDN_N];   /* each line's absorption filter */
    shelf onset;              /* the decay of the pre-delay time */
    double gin[ROOM_FDN_N];   /* input taps, a bent sign pattern / 4 */
    double gl[ROOM_FDN_N];    /* left output taps */
    double gr[ROOM_FDN_N];    /* right output taps, orthogonal to gl */
    size_t bytes;             /* room_fdn_size, for clear */
};

/* Where everything of an FDN goes, from the config alone (size and init
 * share it). */
typedef struct fdn_plan {
    int len[ROOM_FDN_N];
    int npre;
    size_t head; /* bytes of the struct, rounded up to 16 */
    size_t size; /* all bytes */
} fdn_plan;

/* ---- geometry ---- */

static int box_ok(const double *b) {
    for (int a = 0; a < 3; a++)
        if (!isfinite(b[a]) || !isfinite(b[a + 3]) || !(b[a] < b[a + 3]))
            return 0;
    return 1;
}

static int t60_ok(double t) {
    return t >= ROOM_T60_MIN && t <= ROOM_T60_MAX;
}

static int room_ok(const room_config *cfg) {
    return cfg && box_ok(cfg->box) && t60_ok(cfg->t60_low) && t60_ok(cfg->t60_high) && cfg->order >= 0 &&
           cfg->order <= ROOM_MAX_ORDER && isfinite(cfg->c) && cfg->c > 0;
}

static int fdn_ok(const room_config *cfg) {
    return room_ok(cfg) && cfg->fs >= ROOM_FS_MIN && cfg->fs <= ROOM_FS_MAX;
}

int room_contains(const room_config *cfg, const double p[3]) {
    for (int a = 0; a < 3; a++)
        if (!(p[a] >= cfg->box[a] && p[a] <= cfg->box[a + 3]))
            return 0;
    return 1;
}

double room_volume(const room_config *cfg) {
    const double *b = cfg->box;
    return box_ok(b) ? (b[3] - b[0]) * (b[4] - b[1]) * (b[5] - b[2]) : 0;
}

double room_surface(const room_config *cfg) {
    const double *b = cfg->box;
    double x = b[3] - b[0], y = b[4] - b[1], z = b[5] - b[2];
    return box_ok(b) ? 2 * (x * y + y * z + z * x) : 0;
}

/* Mean free path 4V/S, m. */
static double mean_free_path(const room_config *cfg) {
    return 4 * room_volume(cfg) / room_surface(cfg);
}

/* Eyring's pressure reflection coefficient for a T60 (room.h). */
static double reflection(const room_config *cfg, double t60) {
    return exp(-12 * LN10 * room_volume(cfg) / (cfg->c * room_surface(cfg) * t60));
}

/* ---- image sources ---- */

int room_max_images(int order) {
    int n = 0;
    for (int k = 1; k <= order && k <= ROOM_MAX_ORDER; k++)
        n += 4 * k * k + 2;
    return n;
}

/* The coordinate, from the lower wall, of the image after j reflections
 * along an axis of length L with the source at u: for even j, u + jL or
 * u - jL; for odd j, (j + 1)L - u or -(j - 1)L - u (side 0 or 1). */
static double axis_image(double u, double L, int j, int side) {
    if (j % 2 == 0)
        return side ? u - j * L : u + j * L;
    return side ? -(j - 1) * L - u : (j + 1) * L - u;
}

/* Appends the images of exactly k reflections to out[w..max); returns the
 * new count.  Each split of k into (jx, jy, jz) has two images per axis
 * with j > 0 and one per axis with j = 0, picked by the bits of `side`. */
static int images_of_order(const room_config *cfg, const double u[3], int k, double gain, double hf,
                           room_image *out, int w, int max) {
    for (int jx = 0; jx <= k; jx++)
        for (int jy = 0; jy <= k - jx; jy++) {
            int j[3] = {jx, jy, k - jx - jy};
            for (int side = 0; side < 8; side++) {
                int a, dup = 0;
                for (a = 0; a < 3; a++)
                    dup |= j[a] == 0 && (side >> a & 1);
                if (dup)
                    continue;
                if (w == max)
                    return w;
                for (a = 0; a < 3; a++)
                    out[w].pos[a] = cfg->box[a] +
                                    axis_image(u[a], cfg->box[a + 3] - cfg->box[a], j[a], side >> a & 1);
                out[w].reflections = k;
                out[w].gain = gain;
                out[w].hf = hf;
                w++;
            }
        }
    return w;
}

int room_images(const room_config *cfg, const double src[3], room_image *out, int max) {
    if (!room_ok(cfg) || !src || max < 0 || (max > 0 && !out))
        return WDRT_INVALID_ARGS;
    if (!room_contains(cfg, src))
        return WDRT_INVALID_ARGS;
    double u[3];
    for (int a = 0; a < 3; a++)
        u[a] = src[a] - cfg->box[a];
    double blo = reflection(cfg, cfg->t60_low), bhi = reflection(cfg, cfg->t60_high);
    int w = 0;
    for (int k = 1; k <= cfg->order; k++)
        w = images_of_order(cfg, u, k, pow(blo, k), pow(bhi, k), out, w, max);
    return w;
}

/* ---- the FDN's design ---- */

static int is_prime(int n) {
    if (n < 2)
        return 0;
    for (int d = 2; d * d <= n; d++)
        if (n % d == 0)
            return 0;
    return 1;
}

/* The first prime >= n.  Lengths stay below 2 10^5 samples, where prime
 * gaps are under 100. */
static int next_prime(int n) {
    for (int k = 0; k < 1000; k++)
        if (is_prime(n + k))
            return n + k;
    assert(0 && "no prime within 1000");
    return n;
}

/* Lines spread geometrically over an octave from a base: the travel time
 * of one mean free path (so a pass through a line is about one
 * reflection), but no less than Jot's modal density asks for the longer
 * T60 (the lines' mean is sqrt(2) base), within [LINE_MIN, LINE_MAX]. */
static void plan_lines(const room_config *cfg, int len[ROOM_FDN_N]) {
    double t60 = fmax(cfg->t60_low, cfg->t60_high);
    double base = fmax(mean_free_path(cfg) / cfg->c, MODAL_DENSITY * t60 / (sqrt(2.0) * ROOM_FDN_N));
    base = fmin(fmax(base, LINE_MIN), LINE_MAX) * cfg->fs;
    int prev = 1;
    for (int i = 0; i < ROOM_FDN_N; i++) {
        double t = base * pow(2.0, (double)i / (ROOM_FDN_N - 1));
        prev = len[i] = next_prime(t > prev + 1 ? (int)lround(t) : prev + 1);
    }
}

/* The pre-delay: the mixing time of room.h less the shortest line. */
static int plan_predelay(const room_config *cfg, int len0) {
    double mfp = fmin(mean_free_path(cfg) / cfg->c, LINE_MAX);
    long n = lround((cfg->order + 1) * mfp * cfg->fs) - len0;
    return n < 1 ? 1 : (int)n;
}

static size_t align16(size_t n) {
    return (n + 15) & ~(size_t)15;
}

static int fdn_plan_make(const room_config *cfg, fdn_plan *p) {
    if (!fdn_ok(cfg))
        return 0;
    plan_lines(cfg, p->len);
    p->npre = plan_predelay(cfg, p->len[0]);
    p->head = align16(sizeof(room_fdn));
    p->size = p->head + (size_t)p->npre * sizeof(double);
    for (int i = 0; i < ROOM_FDN_N; i++)
        p->size += (size_t)p->len[i] * sizeof(double);
    return 1;
}

size_t room_fdn_size(const room_config *cfg) {
    fdn_plan p;
    return fdn_plan_make(cfg, &p) ? p.size : 0;
}

double room_mixing_time(const room_config *cfg) {
    fdn_plan p;
    return fdn_plan_make(cfg, &p) ? (p.npre + p.len[0]) / cfg->fs : 0;
}

/* ---- shelves ---- */

/* The shelf's squared gains at DC (x) and Nyquist (y) that pass through
 * p at warped frequency^2 w1 and q at w2, with crossover^2 a: the 2x2
 * solve of room_wall_filter_coefs. */
static void shelf_solve(double w1, double w2, double p, double q, double a, double *x, double *y) {
    *y = (q * (a + w2) - p * (a + w1)) / (w2 - w1);
    *x = (p * (a + w1) - *y * w1) / a;
}

/* A line's loop gain may bend only so far beyond its targets: T60 at DC
 * within [T60 low / F, F T60 low], at Nyquist within [T60 high / F,
 * F T60 high].  Since p, q < 1 this keeps x, y < 1: the loop is stable. */
static int shelf_inside(double p, double q, double x, double y, double F) {
    return x >= pow(p, F) && x <= pow(p, 1 / F) && y >= pow(q, F) && y <= pow(q, 1 / F);
}

/* The crossovers^2 a for which the fit stays inside those bounds: x and y
 * move the same way with a (both fall as a grows when p > q, both rise
 * when p < q), and each reaches its bound X, Y at one a (solving
 * shelf_solve for a):
 *   x = X at a = w1 w2 (q - p) / (w2 (p - X) - w1 (q - X)),
 *   y = Y at a = (w2 (q - Y) - w1 (p - Y)) / (p - q).
 * Returns 1 with the window (lo, hi), or 0 if it is empty. */
static int shelf_window(double w1, double w2, double p, double q, double F, double *lo, double *hi) {
    double X = p > q ? pow(p, 1 / F) : pow(p, F), Y = p > q ? pow(q, F) : pow(q, 1 / F);
    double dx = w2 * (p - X) - w1 * (q - X);
    if (p == q || dx == 0)
        return 0;
    *lo = w1 * w2 * (q - p) / dx;
    *hi = (w2 * (q - Y) - w1 * (p - Y)) / (p - q);
    return *lo > 0 && *hi > *lo && isfinite(*hi);
}

static void shelf_set(shelf *s, double g0, double gpi, double k) {
    s->b0 = (g0 * k + gpi) / (k + 1);
    s->b1 = (g0 * k - gpi) / (k + 1);
    s->a1 = (k - 1) / (k + 1);
    s->z = 0;
}

/* Fits x, y through the targets with the crossover in the middle of the
 * window of bound F; 0 if there is none. */
static int shelf_fit_within(double w1, double w2, double p, double q, double F, double *a, double *x, double *y) {
    double lo, hi;
    if (!shelf_window(w1, w2, p, q, F, &lo, &hi))
        return 0;
    *a = sqrt(lo * hi);
    shelf_solve(w1, w2, p, q, *a, x, y);
    return shelf_inside(p, q, *x, *y, F);
}

/* The absorption filter of a line with gains g1 at f_low and g2 at f_high
 * (both < 1), fitted exactly at the two bands: with the crossover at their
 * geometric mean if the T60s at DC and Nyquist stay within a factor 2 of
 * their bands', else in the middle of the crossovers that keep them so, or
 * within a factor 8 (lines that lose many dB per pass, in dead rooms), or,
 * failing all, g1 at DC and g2 at Nyquist. */
static void loop_shelf(shelf *s, double g1, double g2, double fs) {
    const double pi = 3.14159265358979323846;
    double f1, f2, x, y;
    room_bands(fs, &f1, &f2);
    double w1 = pow(tan(pi * f1 / fs), 2), w2 = pow(tan(pi * f2 / fs), 2);
    double p = g1 * g1, q = g2 * g2, a = sqrt(w1 * w2);
    shelf_solve(w1, w2, p, q, a, &x, &y);
    if (!shelf_inside(p, q, x, y, 2) && !shelf_fit_within(w1, w2, p, q, 2, &a, &x, &y) &&
        !shelf_fit_within(w1, w2, p, q, 8, &a, &x, &y))
        x = p, y = q, a = sqrt(w1 * w2);
    shelf_set(s, sqrt(x), sqrt(y), sqrt(a));
}

/* The gain of `seconds` of decay at a T60. */
static double decay(double seconds, double t60) {
    return pow(10.0, -3 * seconds / t60);
}

/* Taps.  Input: the bent function i0 i1 + i2 i3 (mod 2) as signs, whose
 * Walsh transform is flat, so the first pass through H16 spreads an
 * impulse evenly over all 16 lines.  Outputs: that pattern flipped by
 * bit 0 (left) or bit 1 (right), orthogonal to each other; scaled so each
 * output's energy per sample, sum(gl^2) sum(gin^2) / (total length) in an
 * FDN whose energy spreads evenly over its cells, is 4 pi c / (V fs). */
static void set_taps(room_fdn *f, const room_config *cfg) {
    const double pi = 3.14159265358979323846;
    double total = 0;
    for (int i = 0; i < ROOM_FDN_N; i++)
        total += f->len[i];
    double level = 4 * pi * cfg->c / (room_volume(cfg) * cfg->fs);
    double out = sqrt(level * total / ROOM_FDN_N);
    for (int i = 0; i < ROOM_FDN_N; i++) {
        int bent = ((i & 1) & (i >> 1 & 1)) ^ ((i >> 2 & 1) & (i >> 3 & 1));
        f->gin[i] = (bent ? -1.0 : 1.0) / sqrt((double)ROOM_FDN_N);
        f->gl[i] = ((bent ^ (i & 1)) ? -1.0 : 1.0) * out;
        f->gr[i] = ((bent ^ (i >> 1 & 1)) ? -1.0 : 1.0) * out;
    }
}

static void set_filters(room_fdn *f, const room_config *cfg) {
    for (int i = 0; i < ROOM_FDN_N; i++) {
        double t = f->len[i] / cfg->fs;
        loop_shelf(&f->loss[i], decay(t, cfg->t60_low), decay(t, cfg->t60_high), cfg->fs);
    }
    double t = f->npre / cfg->fs;
    room_wall_filter_coefs(decay(t, cfg->t60_low), decay(t, cfg->t60_high), cfg->fs, &f->onset.b0,
                           &f->onset.b1, &f->onset.a1);
}

room_fdn *room_fdn_init(const room_config *cfg, void *mem) {
    fdn_plan p;
    if (!mem || ((uintptr_t)mem & 15) || !fdn_plan_make(cfg, &p))
        return NULL;
    memset(mem, 0, p.size);
    room_fdn *f = mem;
    double *cell = (double *)((char *)mem + p.head);
    for (int i = 0; i < ROOM_FDN_N; i++) {
        f->len[i] = p.len[i];
        f->line[i] = cell;
        cell += p.len[i];
    }
    f->pre = cell;
    f->npre = p.npre;
    f->bytes = p.size;
    set_taps(f, cfg);
    set_filters(f, cfg);
    return f;
}

void room_fdn_clear(room_fdn *f) {
    memset((char *)f + align16(sizeof(room_fdn)), 0, f->bytes - align16(sizeof(room_fdn)));
    memset(f->pos, 0, sizeof f->pos);
    f->prepos = 0;
    for (int i = 0; i < ROOM_FDN_N; i++)
        f->loss[i].z = 0;
    f->onset.z = 0;
}

/* ---- running ---- */

static double flush(double v) {
    return fabs(v) < FLUSH ? 0 : v;
}

static double shelf_run(shelf *s, double x) {
    double y = flush(s->b0 * x + s->z);
    s->z = s->b1 * x - s->a1 * y;
    return y;
}

/* v <- H16 v / 4, the fast Walsh-Hadamard transform: orthogonal, and
 * exactly so up to rounding since the scale is a power of two. */
static void hadamard16(double *v) {
    for (int h = 1; h < ROOM_FDN_N; h *= 2)
        for (int i = 0; i < ROOM_FDN_N; i += 2 * h)
            for (int j = i; j < i + h; j++) {
                double a = v[j], b = v[j + h];
                v[j] = a + b;
                v[j + h] = a - b;
            }
    for (int i = 0; i < ROOM_FDN_N; i++)
        v[i] *= 0.25;
}

/* The input after the pre-delay and its shelf. */
static double predelay(room_fdn *f, double x) {
    double d = f->pre[f->prepos];
    f->pre[f->prepos] = shelf_run(&f->onset, x);
    f->prepos = f->prepos + 1 == f->npre ? 0 : f->prepos + 1;
    return d;
}

/* One sample: the lines' outputs through their absorption filters are
 * tapped for the outputs, mixed by H16 / 4 and fed back with the input. */
static void tick(room_fdn *f, double x, double *l, double *r) {
    double v[ROOM_FDN_N], yl = 0, yr = 0;
    double d = predelay(f, x);
    for (int i = 0; i < ROOM_FDN_N; i++) {
        v[i] = shelf_run(&f->loss[i], f->line[i][f->pos[i]]);
        yl += f->gl[i] * v[i];
        yr += f->gr[i] * v[i];
    }
    hadamard16(v);
    for (int i = 0; i < ROOM_FDN_N; i++) {
        f->line[i][f->pos[i]] = v[i] + f->gin[i] * d;
        f->pos[i] = f->pos[i] + 1 == f->len[i] ? 0 : f->pos[i] + 1;
    }
    *l += yl;
    *r += yr;
}

void room_fdn_process(room_fdn *f, const double *in, double *out_l, double *out_r, int n) {
    for (int k = 0; k < n; k++)
        tick(f, in[k], &out_l[k], &out_r[k]);
}

/* ---- for tests ---- */

void room_fdn_lengths(const room_fdn *f, int len[ROOM_FDN_N]) {
    memcpy(len, f->len, sizeof f->len);
}

static void shelf_identity(shelf *s) {
    s->b0 = 1;
    s->b1 = s->a1 = s->z = 0;
}

void room_fdn_bypass_filters(room_fdn *f) {
    for (int i = 0; i < ROOM_FDN_N; i++)
        shelf_identity(&f->loss[i]);
    shelf_identity(&f->onset);
}

static double sum_squares(const double *v, int n) {
    double s = 0;
    for (int i = 0; i < n; i++)
        s += v[i] * v[i];
    return s;
}

double room_fdn_energy(const room_fdn *f) {
    double e = sum_squares(f->pre, f->npre) + f->onset.z * f->onset.z;
    for (int i = 0; i < ROOM_FDN_N; i++)
        e += sum_squares(f->line[i], f->len[i]) + f->loss[i].z * f->loss[i].z;
    return e;
}

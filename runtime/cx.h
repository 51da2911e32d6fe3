/*
 * cx.h - simplicial complexes heard through their waves, after Axen
 * and Choi ("Using additive sound synthesis to analyze simplicial
 * complexes").  Internal to libwdrt: not part of the public API.
 *
 * A complex is read from a file (complex_read.c: Lutz's
 * `NAME=[[1,2,3],...]` lists or one facet per line, an optional
 * coordinate section) and is the closure of its facets (complex.c): every face of every facet is one of its
 * simplices, each stored once with its vertices (ascending) and its
 * boundary faces, so that walking down (faces) or up (cofaces) costs O(1)
 * per step.
 *
 * Waves.  From a start vertex u, wave 0 is u and wave i the link of the
 * ball of the waves before it: the simplices whose vertices all lie at
 * graph distance i from u and that make a simplex with some vertex at
 * distance i - 1.  That is the link of u once the visited part is
 * contracted onto it (the paper's Figure 6); it is computed in one pass
 * over the simplices (a simplex with exactly one vertex w at its lowest
 * distance puts its face opposite w in the next wave).  Each wave splits
 * into components (of its 1-skeleton), and each component, a complex of
 * its own, is traversed again from its lowest-numbered vertex: the tree
 * of waves, levels d (the complex's components) down to 1.  Every level
 * costs one pass over the simplices and vertices, so the whole tree takes
 * time and memory linear in the number of simplices (times the depth).
 *
 * Sound (the paper's section 7): every node of the tree becomes a note of
 * an additive score (complex_score.c), rendered by a voice class built
 * at run time (complex_source.c) that an engine hosts like any other.
 *
 * Memory: every object here is malloc'ed by its constructor and freed by
 * its free function; nothing is global.  None of this is real-time safe
 * except the source class's process (complex_source.c).
 */
#ifndef WDRT_COMPLEX_H
#define WDRT_COMPLEX_H

#include <stddef.h>
#include <stdio.h>

#include "wdvoice.h"

#if defined(__GNUC__)
#define CX_HIDDEN __attribute__((visibility("hidden")))
#else
#define CX_HIDDEN
#endif

/* A facet has at most this many vertices (dimension 15): the closure of
 * one facet has 2^16 - 1 faces. */
#define CX_MAX_VERTS 16
/* Coordinates a vertex may have. */
#define CX_MAX_COORDS 16

/* ---- complexes ---- */

typedef struct cx_complex {
    char *path;      /* the file it came from (a copy) */
    char *name;      /* the list's name in a Lutz file, or NULL */
    int nv;          /* vertices: ids 0..nv-1 in increasing order of label;
                        the simplex with id v is the vertex v */
    int dim;         /* largest dimension of a simplex (0 for points) */
    int ns;          /* simplices, vertices included */
    long *label;     /* [nv] each vertex's number in the file */
    int *off;        /* [ns + 1] simplex s has off[s+1] - off[s] vertices */
    int *vert;       /* its vertices: vert[off[s] ..], ascending */
    int *face;       /* face[off[s] + j]: its face without vertex j (dim >= 1) */
    int *cooff;      /* [ns + 1] cofaces of s (one dimension up): */
    int *cof;        /* cof[cooff[s] .. cooff[s+1]) */
    int ncoord;      /* coordinates per vertex, 0: none given */
    double *coord;   /* [nv * ncoord] */
    unsigned long long steps; /* the build's work, counted: hash probes, vertices
                        copied and compared, faces filed (not the sort of
                        the labels); linear in ns but for the labels'
                        binary searches */
} cx_complex;

static inline int cx_dim(const cx_complex *K, int s) { return K->off[s + 1] - K->off[s] - 1; }

/* Reads the complex of file `path` (text: len bytes, need not end in NUL).
 * `name` picks a list of a Lutz file by its name (NULL: the first).
 * Returns it, or NULL with "PATH:LINE:COL: error: MESSAGE" and the line
 * and a caret (or "PATH: error: MESSAGE") in err. */
CX_HIDDEN cx_complex *cx_parse(const char *path, const char *text, size_t len, const char *name,
                               char *err, size_t errlen);
/* The same from the file itself ("PATH: error: cannot read: ..."). */
CX_HIDDEN cx_complex *cx_read_file(const char *path, const char *name, char *err, size_t errlen);

/* The closure of nf facets given by vertex labels: facet i has the
 * labels lab[fo[i] .. fo[i+1]) (distinct, any order, at most
 * CX_MAX_VERTS).  A facet listed twice, or a repeated label, gives NULL
 * and a message in err (no position).  For tests and generators. */
CX_HIDDEN cx_complex *cx_from_facets(int nf, const int *fo, const long *lab, char *err, size_t errlen);

CX_HIDDEN void cx_free(cx_complex *K);

/* The id of the vertex labelled `label`, or -1. */
CX_HIDDEN int cx_vertex(const cx_complex *K, long label);

/* The simplex with the given vertex ids (any order), or -1. */
CX_HIDDEN int cx_find(const cx_complex *K, const int *v, int n);

/* ---- the tree of waves ---- */

/* One wave component (or, at the top, one component of the complex). */
typedef struct cx_node {
    int level;   /* the paper's label: d for the complex's components,
                    d - 1 for their waves, and so on down to 1 */
    int wave;    /* its wave's number in the parent's traversal (0: the
                    start vertex); 0 for a top */
    int comp;    /* its number among its wave's components, from 1 (tops:
                    among the complex's components, the start's first) */
    int ncomp;   /* components of its wave */
    int parent;  /* node index; -1 for a top */
    int start;   /* the vertex its own traversal starts at */
    int nverts;  /* its vertices */
    int nsimp;   /* its simplices, vertices included */
    int maxdim;  /* its largest simplex's dimension */
    int first;   /* its children, nodes [first, first + nchild), by wave */
    int nchild;  /* then component; none at the lowest level */
    int nwaves;  /* waves of its traversal (0 at the lowest level) */
    double turn; /* mean angle (rad) its top simplices turn from their
                    neighbours; see cx_turns */
    int npairs;  /* neighbouring pairs that mean is over */
} cx_node;

typedef struct cx_tree {
    int d;         /* the complex's dimension: the tops' level */
    int leaf;      /* the lowest level: 1 (0 for a graph, and for points) */
    int nnodes;
    cx_node *node; /* level by level, tops first; children contiguous */
    int *nodeof;   /* [(level - leaf) * nv + v]: the node vertex v lies in
                      at each level; its wave and component numbers are
                      that node's (the paper's vertex list) */
    signed char *lowest; /* [ns] the lowest level at which a simplex lies
                      in a wave (d: in none below the top); the paper's
                      simplex list */
    unsigned long long steps; /* the walk's work, counted: cofaces visited,
                      union-find steps, simplices and vertices passed over
                      level by level */
} cx_tree;

/* The tree of waves of K from vertex id `start` (-1: vertex 0, the
 * lowest-numbered); components of K not holding the start are traversed
 * after its own, each from its lowest-numbered vertex, in that order.
 * Returns NULL when memory runs out. */
CX_HIDDEN cx_tree *cx_waves(const cx_complex *K, int start);
CX_HIDDEN void cx_tree_free(cx_tree *T);

/* Fills each node's turn: the mean, over pairs of its top-dimensional
 * simplices that share a face of one dimension less, of the angle the
 * second turns away from the first (0: flat, pi: folded back).  With
 * coordinates it is measured in space: the directions of the two
 * opposite vertices, each taken perpendicular to the shared face, make
 * an angle phi and the turn is pi - phi.  Without them it is read from
 * the parent complex: the two opposite vertices lie on the link of the
 * shared face there (for a manifold, a cycle of L vertices) at graph
 * distance g, and the turn is pi (1 - 2g/L) -- on a flat, regular
 * triangulation the same angle as in space.  A face shared by three or
 * more simplices (a branch) counts pi for each one past the first.
 * Linear in the number of simplices (times the size of the links). */
CX_HIDDEN void cx_turns(const cx_complex *K, cx_tree *T);

/* Prints one line per node, parent before child (depth first):
 * `dim=D wave=I component=C vertices=V simplices=S parent=P`, P the line
 * (from 1) of the parent, 0 for a top. */
CX_HIDDEN void cx_tree_print(FILE *f, const cx_tree *T);

/* ---- the additive score ---- */

enum { CX_TOP, CX_GROUP, CX_PARTIAL };

/* Six harmonics make a group's sawtooth (the paper's spectral object). */
#define CX_HARMONICS 6

typedef struct cx_note {
    double on;    /* s from the start of the traversal */
    double dur;   /* s */
    double freq;  /* Hz: the partial's, or a group's fundamental */
    double amp;   /* linear: the peak its partials can reach together */
    double rough; /* groups: 0 a sine .. 1 the six-partial sawtooth */
    int kind;     /* CX_TOP, CX_GROUP or CX_PARTIAL */
    int node;     /* in the tree */
} cx_note;

typedef struct cx_sound_opts {
    double tempo;    /* speed factor: every time is divided by it (1) */
    double step;     /* s a 1-wave lasts at tempo 1 (0.24) */
    double offset;   /* s between the onsets of a split's components at
                        tempo 1 (0.04) */
    double granular; /* explosion factor 0..1 of the granular rendering;
                        negative: off (-1) */
} cx_sound_opts;

CX_HIDDEN cx_sound_opts cx_sound_opts_init(void);

typedef struct cx_score {
    int nnotes;
    cx_note *note;   /* ascending onsets */
    double length;   /* s: the end of the last note */
    double step, offset; /* s, after the tempo */
    double granular; /* as in the options */
    int maxactive;   /* most notes sounding at once (bounds the voice) */
} cx_score;

/* The frequency the paper gives a wave of v vertices in a complex of n:
 * 100 + 1500 (2^(4 (1 - log v / log n)) - 1) / 15 Hz, from 100 Hz (the
 * whole complex) to 1600 Hz (one vertex); 100 Hz when v >= n. */
CX_HIDDEN double cx_freq(int v, int n);

/* The score of a tree (cx_turns already run).  Durations are built
 * bottom up: a node at the lowest level lasts one step; a wave of a
 * node lasts as long as its last component, the c-th of them starting
 * (c - 1) offsets after the first; a node lasts the sum of its waves; the
 * tops follow one another.  Every node is one note: a top is one partial
 * at 100 Hz, softened after its onset; the nodes one level below the top
 * are groups of six harmonics whose shape follows their roughness
 * (min(1, turn / (pi/2))); lower nodes are single partials.  Each level
 * has a fixed share of full scale, split among the components sounding
 * at once (a node gets its parent's part divided by its wave's
 * components), so the sum never exceeds 0.9.  NULL when memory runs
 * out. */
CX_HIDDEN cx_score *cx_score_new(const cx_tree *T, const cx_sound_opts *o);
CX_HIDDEN void cx_score_free(cx_score *s);

/* ---- the source (complex_source.c) ---- */

/* A voice class built at run time around one score: no inputs, one
 * output, no params.  It renders the score from frame 0 of its own time,
 * after `at` seconds of silence; energy() is the time of sound left (s),
 * so an engine puts it to sleep once it has played.  A strike with no
 * targets (set_ic with n = 0) plays the traversal again from that frame.
 * The score and this object must outlive the engine. */
typedef struct cx_source {
    wdv_class cls;
    wdv_port out;
    const cx_score *score;
    double at;       /* s of silence before the traversal */
} cx_source;

/* Makes the class of `score`; the pool that hosts it needs bind =
 * cx_source_bind and data = src. */
CX_HIDDEN void cx_source_init(cx_source *src, const cx_score *score, double at);
/* What one sounding note costs, ns per sample (a little above the ~23
 * measured on x86-64 at -O2): a budget's estimate for a source. */
#define CX_NOTE_NS 25.0
CX_HIDDEN void cx_source_bind(void *state, const void *data);

#endif

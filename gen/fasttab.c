/* fasttab.c: the tables of the fast diode solver, which every voice that
 * uses it carries as constant data.  They are made by the voice's own
 * template code (templates/nl_fast_table.c.tmpl), once. */
#include <math.h>

#include "gen.h"

#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wunused-function" /* the kernels come with the table's layout */
#endif
#include "../templates/nl_wright.c.tmpl"
#include "../templates/nl_fast.c.tmpl"
#include "../templates/nl_fast_table.c.tmpl"

const double *fast_tables(int *n) {
    static double om[OM_SIZE];
    static int made;
    if (!made) {
        omega_table(om);
        made = 1;
    }
    *n = OM_SIZE;
    return om;
}

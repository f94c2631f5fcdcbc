/* stream.c -- run an exported compensator over a CSV stream, one sample at a time.
 *
 * Reads CSV from stdin: a header line, then rows "t,y_ref" (time and desired output, e.g. a
 * file `stageid compensate` reads); writes CSV to stdout: "t,<name>" and one row per sample
 * with the drive.  Build (see the Makefile):
 *
 *   stageid export c hyst.json --prefix comp --inverse -o build
 *   cc -std=c99 -O3 -Ibuild stream.c build/comp.c -o build/stream -lm
 *   ./build/stream V < reference.csv > drive.csv
 *
 * comp_step is all a real-time loop needs: comp_init(&s) once, comp_step(&s, &y_ref, &u) per
 * sample (no heap, no I/O inside; the state is the caller's).
 */
#include <stdio.h>
#include <stdlib.h>

#include "comp.h"

int main(int argc, char **argv)
{
    const char *name = argc > 1 ? argv[1] : "u";
    char line[1024];
    long row = 1;
    comp_state state;

    comp_init(&state);
    if (!fgets(line, sizeof line, stdin)) {
        fprintf(stderr, "stream: empty input; expected a header line and rows t,y_ref\n");
        return 2;
    }
    printf("t,%s\n", name);
    while (fgets(line, sizeof line, stdin)) {
        char *end;
        double t, y_ref, u;
        ++row;
        t = strtod(line, &end);
        if (*end != ',') {
            fprintf(stderr, "stream: row %ld: expected t,y_ref\n", row);
            return 2;
        }
        y_ref = strtod(end + 1, &end);
        comp_step(&state, &y_ref, &u);
        printf("%.17g,%.17g\n", t, u);
    }
    return 0;
}

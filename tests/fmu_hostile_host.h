/* SPDX-License-Identifier: BSD-2-Clause */
/* What the hostile host's two files share: fmu_hostile_host.c (the host, its FMI calls, the
   scenarios) and fmu_hostile_nonsense.c (the nonsense calls, one on each instance). */

#ifndef FTC_HOSTILE_HOST_H
#define FTC_HOSTILE_HOST_H

#include "fmi2FunctionTypes.h" /* the official FMI 2.0 types (fmu_src/cbase/fmi) */

typedef void *component; /* an FMI 2.0 component or FMI 3.0 instance */

struct result {
    int status;   /* of the call under test; -2: skipped */
    int instance; /* the instance under test exists */
    double extra; /* a figure of the scenario */
};

enum { OK, WARNING, DISCARD, ERROR, FATAL };

extern int version, out_vr;              /* FMI 2 or 3; a Real output's value reference */
extern int messages, null_categories;    /* the FMU's messages since under_test() */
extern int messages_of_call;             /* those of a nonsense call when others follow it; -1 */
extern char first[512];                  /* the first message of status warning or worse */

void *fn(const char *name);              /* the FMU's function `name` (exits if it has none) */
component fresh(const char *name);       /* an instance, its resources and token right */
int initialize(component c);             /* the experiment set up and initialization done */
void free_instance(component c);

/* fmu_hostile_nonsense.c: whether `name` is a nonsense call; it on an instance of its own (extra:
   the messages the call logged). */
int is_nonsense(const char *name);
struct result nonsense(const char *name);

#endif

/* SPDX-License-Identifier: BSD-2-Clause */
/* The pool (shim.h): pythonfmu's components kept for reuse after their instance is freed. */

#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "shim.h"

/* ---- Pool ----------------------------------------------------------------------------------------

   pythonfmu 0.7.0 leaks 16-34 KB every time it constructs a component (its findClass runs the
   FMU's script again and keeps references to the classes it made; each constructor also puts the
   resources folder on sys.path once more), and nothing when it resets one. So a freed instance's
   component is kept, and the next fmi2Instantiate with the same resources folder and visibility
   resets it (pythonfmu constructs a new Python slave from the class it found, as fmi2Reset does)
   instead of constructing another: one of the same instance name if there is one, else any whose
   slave is the project's (renamable). pythonfmu constructs the new slave under the name it was
   first instantiated with; bind_direct renames it (its instance_name) to the new instance's, and
   the shim's logger gives the host the new name, so hosts that name every instance anew (run0,
   run1, ... as campaign tools and FMPy do) leak nothing either. At most POOL_SIZE are kept; the
   pool is emptied when the shim is unloaded. */

#define POOL_SIZE 16
static ftc_mutex pool_lock = FTC_MUTEX_INIT;
static struct pooled *pool;
static size_t pooled_count;

static struct pooled *take(const char *name, const char *resources, fmi2Boolean visible) {
    ftc_lock(&pool_lock);
    struct pooled **p = &pool;
    while (*p && (strcmp((*p)->name, name) || strcmp((*p)->resources, resources) || (*p)->visible != visible))
        p = &(*p)->next;
    if (!*p) /* none of this name: one that can be renamed */
        for (p = &pool; *p && (!(*p)->renamable || strcmp((*p)->resources, resources) || (*p)->visible != visible);)
            p = &(*p)->next;
    struct pooled *found = *p;
    if (found) {
        *p = found->next;
        pooled_count--;
    }
    ftc_unlock(&pool_lock);
    return found;
}

void give_back(struct pooled *p) {
    p->owner = NULL;
    ftc_lock(&pool_lock);
    int kept = pooled_count < POOL_SIZE;
    if (kept) {
        p->next = pool;
        pool = p;
        pooled_count++;
    }
    ftc_unlock(&pool_lock);
    if (!kept) {
        inner_fmi2FreeInstance(p->c);
        free(p);
    }
}

#ifndef _WIN32 /* see unload(): Windows leaves the components to the end of the process */
void empty_pool(void) {
    ftc_lock(&pool_lock);
    struct pooled *p = pool;
    pool = NULL;
    pooled_count = 0;
    ftc_unlock(&pool_lock);
    while (p) {
        struct pooled *next = p->next;
        inner_fmi2FreeInstance(p->c);
        free(p);
        p = next;
    }
}
#endif

/* pythonfmu's component for a new instance: one from the pool, reset, or a new one. */
struct pooled *component_for(struct instance *i, fmi2Type type, fmi2String guid, const char *resources,
                                    fmi2Boolean visible, fmi2Boolean loggingOn) {
    struct pooled *p = take(i->name, resources, visible);
    if (p) {
        p->owner = i;
        if (inner_fmi2Reset(p->c) < fmi2Error) {
            inner_fmi2SetDebugLogging(p->c, loggingOn, 0, NULL);
            return p;
        }
        p->owner = NULL; /* pythonfmu could not construct the slave again: abandoned, as after fmi2Fatal */
    }
    p = calloc(1, sizeof *p);
    if (!p) return NULL;
    p->owner = i;
    p->callbacks.logger = relay;
    p->callbacks.allocateMemory = calloc;
    p->callbacks.freeMemory = free;
    p->callbacks.componentEnvironment = p;
    snprintf(p->name, sizeof p->name, "%s", i->name);
    snprintf(p->resources, sizeof p->resources, "%s", resources);
    p->visible = visible;
    p->c = inner_fmi2Instantiate(i->name, type, guid, resources, &p->callbacks, visible, loggingOn);
    if (!p->c) {
        free(p);
        return NULL;
    }
    return p;
}


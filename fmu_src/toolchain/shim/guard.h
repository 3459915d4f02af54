/* SPDX-License-Identifier: BSD-2-Clause */
/* What the shim's guard knows of its FMU (guard.c): the model description's instantiation token
   and variables, read once from the unpacked FMU the shim's own file sits in, and where the
   FMU's resources are. Shared by the FMI 2.0 and 3.0 layers. */

#ifndef FTC_GUARD_H
#define FTC_GUARD_H

#include <stddef.h>

/* One variable of the model description. type: 'r' Real/Float64, 'i' Integer/Int32, 'b' Boolean,
   's' String, 'e' any other; causality: 'p' parameter, 'c' calculatedParameter, 'i' input,
   'o' output, 'l' local, 't' independent, 's' structuralParameter; variability: 'c' constant,
   'f' fixed, 't' tunable, 'd' discrete, 'C' continuous; initial: 'e' exact, 'a' approx,
   'c' calculated, 0 not given. */
struct ftc_variable {
    unsigned vr;
    char type, causality, variability, initial;
    char name[96];
};

struct ftc_model {
    char root[4096];   /* the unpacked FMU: <root>/binaries/<platform>/<model>.so */
    char token[160];   /* guid (FMI 2.0) or instantiationToken (FMI 3.0) */
    size_t n;          /* variables, sorted by value reference */
    struct ftc_variable *variables;
    /* the CoSimulation element's capabilities (1: declared true; the order: a number) */
    int can_get_and_set_state, can_serialize_state, directional_derivatives, interpolate_inputs;
    int output_derivative_order;
};

/* The file in the resources folder that names the FMU it belongs to: its GUID (FMI 2.0) or
   instantiation token (FMI 3.0), written by the build (fmu_src/toolchain/build.py, fmi3.py). */
#define IDENTITY_FILE "fmu_identity.txt"

/* The build's copy of the model description beside each binary: <binary without extension> + this. */
#define DESCRIPTION_SUFFIX "_modelDescription.xml"

/* Reads the model description of the FMU whose binary is `binary` (the copy beside it, else
   <root>/modelDescription.xml); 0, or -1 and a message. */
int ftc_read_model(const char *binary, struct ftc_model *model, char *why, size_t size);

/* The variable of value reference `vr`, or NULL. */
const struct ftc_variable *ftc_variable(const struct ftc_model *model, unsigned vr);

/* The resources folder to give the model: `given` (a file URI, or a native path as FMI 3.0 passes
   it) when it holds this FMU's resources (resources/slavemodule.txt, and IDENTITY_FILE naming this
   FMU's token), else the FMU's own
   <root>/resources. Writes the native path to `out`; 0: `given` is used; 1: the FMU's own is used
   and `note` says why; -1: neither, `note` says why. */
int ftc_resources(const struct ftc_model *model, const char *given, char *out, size_t size, char *note,
                  size_t note_size);

#endif

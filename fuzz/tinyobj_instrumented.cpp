// tinyobjloader's implementation compiled into the OBJ fuzzer, so that its parser is instrumented
// for coverage and sanitizers; these definitions take precedence over the (uninstrumented) shared
// library that phongfit_core links.
#define TINYOBJLOADER_IMPLEMENTATION
#include <tiny_obj_loader.h>

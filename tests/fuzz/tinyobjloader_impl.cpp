// tinyobjloader's implementation, compiled into fuzz_obj so that it is instrumented too.
// TINYOBJLOADER_USE_DOUBLE comes from the target, as in spacewarp_core.
#define TINYOBJLOADER_IMPLEMENTATION
#include <tiny_obj_loader.h>

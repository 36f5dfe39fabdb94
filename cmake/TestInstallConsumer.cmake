# Run as a ctest test (cmake -P): installs the build tree into a scratch prefix, then
# configures, builds and runs tests/install_consumer against it through find_package, and runs
# the examples (examples/) on a cage, a pose and a soup written here, checked by the consumer.
# Inputs: BUILD_DIR, CONSUMER_SOURCE_DIR, EXAMPLES_DIR, WORK_DIR, GENERATOR.
file(REMOVE_RECURSE "${WORK_DIR}")
set(prefix "${WORK_DIR}/prefix")

function(run_step)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "step failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "${out}")
endfunction()

run_step(${CMAKE_COMMAND} --install "${BUILD_DIR}" --prefix "${prefix}")
run_step(${CMAKE_COMMAND} -S "${CONSUMER_SOURCE_DIR}" -B "${WORK_DIR}/build" -G "${GENERATOR}"
         "-DCMAKE_PREFIX_PATH=${prefix}" "-DEXAMPLES_DIR=${EXAMPLES_DIR}" -DCMAKE_BUILD_TYPE=Release)
run_step(${CMAKE_COMMAND} --build "${WORK_DIR}/build")
run_step("${WORK_DIR}/build/consumer")

# A box cage around a quad with normals, the cage moved by (1, 2, 3), and an affine rig that
# moves by the same: both examples must move the quad by (1, 2, 3) and keep its normals.
set(d "${WORK_DIR}/data")
file(WRITE "${d}/cage.obj" "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
     "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")
file(WRITE "${d}/pose.obj" "v 0 1 2\nv 2 1 2\nv 2 3 2\nv 0 3 2\nv 0 1 4\nv 2 1 4\nv 2 3 4\nv 0 3 4\n"
     "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")
file(WRITE "${d}/quad.obj" "v -0.5 -0.5 0.1\nv 0.5 -0.5 0.2\nv 0.5 0.5 0.3\nv -0.5 0.5 0.4\n"
     "vn 0 0 1\nf 1//1 2//1 3//1 4//1\n")
file(WRITE "${d}/shift.json"
     "{\"method\": \"affine\", \"matrix\": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]]}\n")
run_step("${WORK_DIR}/build/deform_soup" "${d}/cage.obj" "${d}/pose.obj" "${d}/quad.obj"
         "${d}/mvc.obj")
run_step("${WORK_DIR}/build/load_rig" "${d}/shift.json" "${d}/quad.obj" "${d}/rig.ply")
run_step("${WORK_DIR}/build/consumer" "${d}/quad.obj" "${d}/mvc.obj" "${d}/rig.ply")
# ARAP on the cage's box (a closed quad mesh): its top turns and rises, its bottom stays.
run_step("${WORK_DIR}/build/edit_surface" "${d}/cage.obj" "${d}/edited.obj" 0.5)
file(STRINGS "${d}/edited.obj" edited REGEX "^v ")
list(GET edited 0 bottom)
list(GET edited 6 top)
if(NOT bottom STREQUAL "v -1 -1 -1" OR top MATCHES "^v [-0-9.e]+ 1 ")
  message(FATAL_ERROR "edit_surface: bottom '${bottom}' should stay, top '${top}' should rise")
endif()
# A bad rig is a one-line error and exit 3.
execute_process(COMMAND "${WORK_DIR}/build/load_rig" "${d}/quad.obj" "${d}/quad.obj" "${d}/x.obj"
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 3 OR EXISTS "${d}/x.obj")
  message(FATAL_ERROR "load_rig on a bad rig: exit ${rc}, ${err}")
endif()
file(REMOVE_RECURSE "${WORK_DIR}")

# tests/package: configures tests/package/subproject (a parent that add_subdirectory()s drape)
# twice in fresh folders: without a build type and default options, then with its own build
# type and all of drape's helpers switched on. The parent fails the configure if drape changed
# its build type or added a target that is not namespaced; this script also reads the cache.
#   cmake -DDRAPE_SOURCE_DIR=<drape> -DWORK=<folder> -DGENERATOR=<generator> -DC=<cc>
#         -DCXX=<c++> -P add_subdirectory.cmake
foreach(var DRAPE_SOURCE_DIR WORK GENERATOR C CXX)
    if(NOT DEFINED ${var})
        message(FATAL_ERROR "add_subdirectory.cmake: -D${var}=... is required")
    endif()
endforeach()
unset(ENV{CMAKE_BUILD_TYPE}) # CMake >= 3.22 takes a default build type from the environment

function(configure_parent name build_type)
    set(dir ${WORK}/${name})
    file(REMOVE_RECURSE ${dir})
    set(type_arg "")
    if(build_type)
        set(type_arg -DCMAKE_BUILD_TYPE=${build_type})
    endif()
    execute_process(COMMAND ${CMAKE_COMMAND} -S ${CMAKE_CURRENT_LIST_DIR}/subproject -B ${dir}
            -G ${GENERATOR} -DCMAKE_C_COMPILER=${C} -DCMAKE_CXX_COMPILER=${CXX}
            -DDRAPE_SOURCE_DIR=${DRAPE_SOURCE_DIR} ${type_arg} ${ARGN}
        RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
    if(NOT code EQUAL 0)
        message(FATAL_ERROR "${name}: configuring the parent failed (${code}):\n${out}\n${err}")
    endif()
    file(STRINGS ${dir}/CMakeCache.txt entry REGEX "^CMAKE_BUILD_TYPE:")
    if(NOT entry STREQUAL "" AND NOT entry MATCHES "^CMAKE_BUILD_TYPE:[A-Z]+=${build_type}$")
        message(FATAL_ERROR "${name}: the parent's cache has '${entry}', expected '${build_type}'")
    endif()
    string(REGEX MATCH "drape as a subdirectory: [^\n]*" summary "${out}")
    message(STATUS "${name}: ${summary}")
endfunction()

configure_parent(no-build-type "" -DEXPECT_HELPERS=OFF)
configure_parent(debug-everything Debug -DEXPECT_HELPERS=ON -DDRAPE_BUILD_SAMPLES=ON
    -DDRAPE_BUILD_TESTS=ON -DDRAPE_BUILD_BENCHMARKS=ON -DDRAPE_BUILD_REPORTS=ON)

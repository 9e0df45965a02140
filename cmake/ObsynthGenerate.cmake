# SPDX-License-Identifier: MIT
# Copyright (c) obsynth authors
#
# ObsynthGenerate.cmake -- generate obsynth observer headers at build time.
#
# Shipped with the obsynth package (lib/cmake/obsynth/) and loaded by find_package(obsynth);
# inside the obsynth build tree it is loaded by cmake/install.cmake.
#
#   obsynth_add_observer(<target>
#     MODEL <file.sym>
#     [METHOD auto | <method>[,<method>...]]   # default auto; e.g. canonical, perfect,
#                                              # "canonical,perfect" or a CMake list; obsynth
#                                              # checks the names (`obsynth --list-methods`)
#     [PRECISION float|double]                 # literal precision and default Scalar
#     [POLES -2,-3]                            # canonical error poles (comma list or CMake list)
#     [REALISATION z|x]                        # canonical observer realisation
#     [OPTIONS <name>=<value>...]              # any design option, passed as --<name>=<value>
#                                              # (e.g. theta=20 kou-gain=1,2 "el-poles=-1,-2")
#     [OUTPUT_DIR <dir>]                       # default <binary dir>/obsynth_gen/<target>
#     [SCOPE PRIVATE|PUBLIC|INTERFACE]         # how <target> gets the include dir and runtime;
#                                              # default PRIVATE (INTERFACE for INTERFACE libs)
#     [OBSYNTH_EXECUTABLE <target-or-path>]    # which obsynth to run (see below)
#     [HEADERS_VAR <var>])                     # receives the list of generated headers
#
# Adds a custom command that runs obsynth when <target> is built, and again whenever the model
# file or the obsynth executable changes. The command writes into the output directory
#   <model>_<method>.hpp (one per method), <model>_report.md, <model>_report.json
# where <model> is the name in the model's `model NAME` statement (as obsynth spells it in
# C++: e.g. `model slawinski17` -> slawinski17_canonical.hpp, class
# obsynth_gen::slawinski17::Slawinski17Canonical). With METHOD auto obsynth picks the design
# and writes <model>_auto.hpp itself, which includes the chosen header and declares
# obsynth_gen::<model>::AutoObserver<...> (an alias of the chosen class) and
# obsynth_gen::<model>::auto_method (its method name): nothing here reads generated files.
#
# The output directory is added to <target>'s include directories, <target> links
# obsynth::runtime (Eigen and the runtime headers), and <target> depends on the generation,
# so `#include "slawinski17_canonical.hpp"` works in its sources.
#
# Which obsynth runs: the OBSYNTH_EXECUTABLE argument, else the variable OBSYNTH_EXECUTABLE,
# else the imported target obsynth::obsynth (from find_package(obsynth)), else the target
# obsynth (inside the obsynth build tree). A target name gets a build-order dependency in the
# same build; a path is used as is. Either way the command depends on the executable file.
#
# The model name is read at configure time, so the model file is a configure dependency:
# renaming the model re-runs CMake and the output names follow.
#
# When the obsynth executable already exists at configure time (find_package(obsynth), or a
# path), METHOD and the OPTIONS names are checked against `obsynth --list-methods --format
# json` there, with a configure error that lists the known ones; inside the obsynth build tree
# obsynth itself checks them when it runs.

include_guard(GLOBAL)
# The functions below keep these policy settings wherever they are called from.
cmake_policy(PUSH)
cmake_policy(VERSION 3.22)

# Note: include_guard(GLOBAL) makes functions global but variables set here would only exist in
# the directory that first included this file, so constants live in functions.

# The C++ spelling obsynth uses for a model name in file names and namespaces (mirrors
# cxx_identifier in synth/cxx.cpp): runs of '_' collapse to one, keywords get a '_' suffix.
function(_obsynth_cxx_identifier name out_var)
  string(REGEX REPLACE "[^A-Za-z0-9_]" "_" s "${name}")
  if(s STREQUAL "" OR s MATCHES "^[0-9]")
    set(s "m_${s}")
  endif()
  string(REGEX REPLACE "__+" "_" s "${s}")
  set(keywords
      alignas alignof and and_eq asm auto bitand bitor bool break case catch char char8_t
      char16_t char32_t class compl concept const consteval constexpr constinit const_cast
      continue co_await co_return co_yield decltype default delete do double dynamic_cast else
      enum explicit export extern false float for friend goto if inline int long mutable
      namespace new noexcept not not_eq nullptr operator or or_eq private protected public
      register reinterpret_cast requires return short signed sizeof static static_assert
      static_cast struct switch template this thread_local throw true try typedef typeid
      typename union unsigned using virtual void volatile wchar_t while xor xor_eq final
      override import module)
  if(s IN_LIST keywords)
    string(APPEND s "_")
  endif()
  set(${out_var} "${s}" PARENT_SCOPE)
endfunction()

# Splits "a,b" / "a;b" / "a, b" into a CMake list.
function(_obsynth_split_list out_var)
  set(items "")
  foreach(arg IN LISTS ARGN)
    string(REPLACE "," ";" parts "${arg}")
    foreach(p IN LISTS parts)
      string(STRIP "${p}" p)
      if(NOT p STREQUAL "")
        list(APPEND items "${p}")
      endif()
    endforeach()
  endforeach()
  set(${out_var} "${items}" PARENT_SCOPE)
endfunction()

# Checks METHOD and OPTIONS names against the registry of an obsynth executable that exists at
# configure time (`--list-methods --format json`); a target built later is skipped (obsynth
# checks them itself when it runs).
function(_obsynth_check_methods fn exe methods option_names)
  set(path "")
  if(TARGET "${exe}")
    get_target_property(imported "${exe}" IMPORTED)
    if(imported)
      foreach(prop IMPORTED_LOCATION IMPORTED_LOCATION_RELEASE IMPORTED_LOCATION_NOCONFIG
                   IMPORTED_LOCATION_RELWITHDEBINFO IMPORTED_LOCATION_DEBUG)
        get_target_property(loc "${exe}" ${prop})
        if(loc AND EXISTS "${loc}")
          set(path "${loc}")
          break()
        endif()
      endforeach()
    endif()
  elseif(EXISTS "${exe}")
    set(path "${exe}")
  endif()
  if(path STREQUAL "")
    return()
  endif()
  execute_process(COMMAND "${path}" --list-methods --format json OUTPUT_VARIABLE listing
                  RESULT_VARIABLE rc ERROR_QUIET)
  if(NOT rc EQUAL 0)
    return()  # an older obsynth without the JSON listing: it checks the names itself
  endif()
  set(known_methods auto all)
  set(known_options "")
  string(JSON n LENGTH "${listing}" methods)
  math(EXPR last "${n} - 1")
  foreach(i RANGE ${last})
    string(JSON name GET "${listing}" methods ${i} name)
    list(APPEND known_methods "${name}")
    string(JSON k LENGTH "${listing}" methods ${i} options)
    if(k GREATER 0)
      math(EXPR klast "${k} - 1")
      foreach(j RANGE ${klast})
        string(JSON oname GET "${listing}" methods ${i} options ${j} name)
        string(JSON qname ERROR_VARIABLE no_qualified GET "${listing}" methods ${i} options ${j}
               qualified)
        list(APPEND known_options "${oname}")
        if(NOT no_qualified)
          list(APPEND known_options "${qname}")  # design.option: for that design alone
        endif()
      endforeach()
    endif()
  endforeach()
  list(REMOVE_DUPLICATES known_options)
  foreach(m IN LISTS methods)
    if(NOT m IN_LIST known_methods)
      string(REPLACE ";" ", " known "${known_methods}")
      message(FATAL_ERROR "${fn}: METHOD '${m}' is not an obsynth design (known: ${known})")
    endif()
  endforeach()
  foreach(o IN LISTS option_names)
    if(NOT o IN_LIST known_options)
      string(REPLACE ";" ", " known "${known_options}")
      message(FATAL_ERROR "${fn}: OPTIONS '${o}' is not an option of any obsynth design "
                          "(known: ${known})")
    endif()
  endforeach()
endfunction()

function(obsynth_add_observer target)
  set(one_value MODEL PRECISION REALISATION OUTPUT_DIR SCOPE OBSYNTH_EXECUTABLE HEADERS_VAR)
  set(multi_value METHOD POLES OPTIONS)
  cmake_parse_arguments(PARSE_ARGV 1 arg "" "${one_value}" "${multi_value}")
  set(fn "obsynth_add_observer(${target})")
  set(poles "")
  if(arg_UNPARSED_ARGUMENTS)
    message(FATAL_ERROR "${fn}: unexpected arguments: ${arg_UNPARSED_ARGUMENTS}")
  endif()
  if(NOT TARGET "${target}")
    message(FATAL_ERROR "${fn}: '${target}' is not a target; call add_executable/add_library first")
  endif()
  get_target_property(aliased "${target}" ALIASED_TARGET)
  if(aliased)
    set(target "${aliased}")
  endif()

  # --- model file and model name ------------------------------------------------------------
  if(NOT arg_MODEL)
    message(FATAL_ERROR "${fn}: MODEL <file.sym> is required")
  endif()
  get_filename_component(model "${arg_MODEL}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
  if(NOT EXISTS "${model}" OR IS_DIRECTORY "${model}")
    message(FATAL_ERROR "${fn}: model file not found: ${model}")
  endif()
  file(STRINGS "${model}" model_lines REGEX "^[ \t]*model[ \t]+[A-Za-z_][A-Za-z0-9_]*")
  list(LENGTH model_lines n_model_lines)
  if(NOT n_model_lines EQUAL 1)
    message(FATAL_ERROR "${fn}: expected exactly one 'model NAME' statement in ${model}, "
                        "found ${n_model_lines}")
  endif()
  string(REGEX MATCH "^[ \t]*model[ \t]+([A-Za-z_][A-Za-z0-9_]*)" _ "${model_lines}")
  _obsynth_cxx_identifier("${CMAKE_MATCH_1}" stem)
  # The output names depend on the model name: re-configure when the model file changes.
  set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS "${model}")

  # --- options -------------------------------------------------------------------------------
  _obsynth_split_list(methods ${arg_METHOD})
  if(NOT methods)
    set(methods auto)
  endif()
  list(REMOVE_DUPLICATES methods)
  set(auto FALSE)
  if("auto" IN_LIST methods)
    list(LENGTH methods n_methods)
    if(NOT n_methods EQUAL 1)
      message(FATAL_ERROR "${fn}: METHOD auto cannot be combined with other methods")
    endif()
    set(auto TRUE)
  endif()
  # Method names are checked by obsynth itself against its design registry (a diagnostic at
  # build time names the known ones).
  string(REPLACE ";" "," methods_csv "${methods}")

  set(cli_options "")
  if(NOT "${arg_PRECISION}" STREQUAL "")
    if(NOT arg_PRECISION MATCHES "^(float|double)$")
      message(FATAL_ERROR "${fn}: PRECISION must be float or double, not '${arg_PRECISION}'")
    endif()
    list(APPEND cli_options --precision "${arg_PRECISION}")
  endif()
  if(NOT "${arg_POLES}" STREQUAL "")
    _obsynth_split_list(poles ${arg_POLES})
    string(REPLACE ";" "," poles "${poles}")
    # "--poles=-2,-3": a separate "-2,-3" argument would look like an option.
    list(APPEND cli_options "--poles=${poles}")
  endif()
  if(NOT "${arg_REALISATION}" STREQUAL "")
    if(NOT arg_REALISATION MATCHES "^(z|x)$")
      message(FATAL_ERROR "${fn}: REALISATION must be z or x, not '${arg_REALISATION}'")
    endif()
    list(APPEND cli_options --realisation "${arg_REALISATION}")
  endif()

  set(option_names "")
  foreach(o IN LISTS arg_OPTIONS)
    if(NOT o MATCHES "^([A-Za-z][A-Za-z0-9-]*)=(.*)$")
      message(FATAL_ERROR "${fn}: OPTIONS entries are <name>=<value>, not '${o}'")
    endif()
    list(APPEND option_names "${CMAKE_MATCH_1}")
    # "--name=value": a separate "-1,-2" argument would look like an option.
    list(APPEND cli_options "--${o}")
  endforeach()

  get_target_property(target_type "${target}" TYPE)
  if(NOT "${arg_SCOPE}" STREQUAL "")
    if(NOT arg_SCOPE MATCHES "^(PRIVATE|PUBLIC|INTERFACE)$")
      message(FATAL_ERROR "${fn}: SCOPE must be PRIVATE, PUBLIC or INTERFACE")
    endif()
    set(scope "${arg_SCOPE}")
  elseif(target_type STREQUAL "INTERFACE_LIBRARY")
    set(scope INTERFACE)
  else()
    set(scope PRIVATE)
  endif()

  # --- the obsynth executable and the runtime ------------------------------------------------
  if(NOT "${arg_OBSYNTH_EXECUTABLE}" STREQUAL "")
    set(exe "${arg_OBSYNTH_EXECUTABLE}")
  elseif(NOT "${OBSYNTH_EXECUTABLE}" STREQUAL "")
    set(exe "${OBSYNTH_EXECUTABLE}")
  elseif(TARGET obsynth::obsynth)
    set(exe obsynth::obsynth)
  elseif(TARGET obsynth)
    set(exe obsynth)
  else()
    message(FATAL_ERROR "${fn}: no obsynth executable: use find_package(obsynth) (which defines "
                        "obsynth::obsynth), or set OBSYNTH_EXECUTABLE to a target or a path")
  endif()
  if(TARGET "${exe}")
    get_target_property(aliased "${exe}" ALIASED_TARGET)
    if(aliased)
      set(exe "${aliased}")
    endif()
    set(exe_command "$<TARGET_FILE:${exe}>")
    # A target name in DEPENDS gives both a build-order dependency (same build) and a file
    # dependency on the executable (imported or built).
    set(exe_depends "${exe}")
  else()
    get_filename_component(exe "${exe}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_SOURCE_DIR}")
    if(NOT EXISTS "${exe}")
      message(FATAL_ERROR "${fn}: OBSYNTH_EXECUTABLE '${exe}' is neither a target nor a file")
    endif()
    set(exe_command "${exe}")
    set(exe_depends "${exe}")
  endif()

  _obsynth_check_methods("${fn}" "${exe}" "${methods}" "${option_names}")

  if(TARGET obsynth::runtime)
    set(runtime obsynth::runtime)
  elseif(TARGET obsynth_runtime)
    set(runtime obsynth_runtime)
  else()
    message(FATAL_ERROR "${fn}: the obsynth::runtime target is missing; use find_package(obsynth)")
  endif()

  # --- output directory and the custom command ----------------------------------------------
  if(NOT "${arg_OUTPUT_DIR}" STREQUAL "")
    get_filename_component(out_dir "${arg_OUTPUT_DIR}" ABSOLUTE BASE_DIR "${CMAKE_CURRENT_BINARY_DIR}")
  else()
    set(out_dir "${CMAKE_CURRENT_BINARY_DIR}/obsynth_gen/${target}")
  endif()
  # Two calls writing the same reports would be two rules for one file.
  get_property(claimed GLOBAL PROPERTY _OBSYNTH_GENERATED_REPORTS)
  set(report_md "${out_dir}/${stem}_report.md")
  if(report_md IN_LIST claimed)
    message(FATAL_ERROR "${fn}: model '${stem}' is already generated into ${out_dir}; give one "
                        "call several methods (METHOD canonical,perfect) or use another OUTPUT_DIR")
  endif()
  set_property(GLOBAL APPEND PROPERTY _OBSYNTH_GENERATED_REPORTS "${report_md}")

  set(reports "${report_md}" "${out_dir}/${stem}_report.json")
  if(auto)
    set(headers "${out_dir}/${stem}_auto.hpp")
  else()
    set(headers "")
    foreach(m IN LISTS methods)
      list(APPEND headers "${out_dir}/${stem}_${m}.hpp")
    endforeach()
  endif()
  set(command "${exe_command}" "${model}" -o "${out_dir}" --method "${methods_csv}" ${cli_options})

  file(RELATIVE_PATH model_rel "${CMAKE_SOURCE_DIR}" "${model}")
  if(model_rel MATCHES "^\\.\\.")
    set(model_rel "${model}")
  endif()
  add_custom_command(
    OUTPUT ${headers} ${reports}
    # A failed run must not leave the headers of an earlier one looking up to date.
    COMMAND "${CMAKE_COMMAND}" -E rm -f ${headers}
    COMMAND ${command}
    DEPENDS "${model}" ${exe_depends}
    COMMENT "obsynth: generating ${stem} observer (${methods_csv}) from ${model_rel}"
    VERBATIM)

  set(gen_target "${target}_obsynth_${stem}")
  if(TARGET "${gen_target}")
    message(FATAL_ERROR "${fn}: target ${gen_target} already exists")
  endif()
  add_custom_target("${gen_target}" DEPENDS ${headers} ${reports} SOURCES "${model}")
  add_dependencies("${target}" "${gen_target}")
  target_include_directories("${target}" ${scope} "$<BUILD_INTERFACE:${out_dir}>")
  target_link_libraries("${target}" ${scope} ${runtime})

  if(arg_HEADERS_VAR)
    set(${arg_HEADERS_VAR} "${headers}" PARENT_SCOPE)
  endif()
endfunction()

cmake_policy(POP)

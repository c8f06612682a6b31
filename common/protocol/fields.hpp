#pragma once
// The field list of a message, written once next to its struct:
//
//   SYNDDS_FIELDS(DriverCommandMsg, vehicle_id, source, frame, steering, throttle, braking)
//
// Code that handles every field alike (the DDS conversions, their tests) visits the list instead
// of naming fields, so a new field is a line in the struct, its name in the list and its member
// in idl/syndds.idl. A field whose IDL member has another name is written (plain, idl), e.g.
// (sequence, number): `sequence` is an IDL keyword.
//
// for_each_field<Msg>(f) calls, in declaration order,
//   f(name, member, wire)
// with the plain name, a pointer to the member and a generic accessor: wire(x) is x.idl_name(),
// the accessor of that member in any type that has one (the fastddsgen types do: a reference for
// a non-const object, a value or const reference for a const one). The accessor is only
// instantiated by code that uses it, so this header and the message headers stay free of DDS.
#include <cstddef>
#include <type_traits>
#include <utility>

namespace syndds::proto {

/// Specialised by SYNDDS_FIELDS; `visit` calls f(name, member, wire) per field, `count` is their
/// number.
template <typename Msg>
struct Fields;

template <typename Msg>
concept HasFields = requires { Fields<Msg>::count; };

template <typename Msg, typename F>
constexpr void for_each_field(F&& f) {
  Fields<Msg>::visit(f);
}

// ---- preprocessor machinery --------------------------------------------------------------
// A C++20 __VA_OPT__ for-each: SYNDDS_PP_FOR_EACH(M, C, a, b, c) gives M(C, a) M(C, b) M(C, c).
#define SYNDDS_PP_PARENS ()
// (4 x 4 x 4 rescans: up to 64 fields.)
#define SYNDDS_PP_EXPAND(...) \
  SYNDDS_PP_EXPAND3(SYNDDS_PP_EXPAND3(SYNDDS_PP_EXPAND3(SYNDDS_PP_EXPAND3(__VA_ARGS__))))
#define SYNDDS_PP_EXPAND3(...) \
  SYNDDS_PP_EXPAND2(SYNDDS_PP_EXPAND2(SYNDDS_PP_EXPAND2(SYNDDS_PP_EXPAND2(__VA_ARGS__))))
#define SYNDDS_PP_EXPAND2(...) \
  SYNDDS_PP_EXPAND1(SYNDDS_PP_EXPAND1(SYNDDS_PP_EXPAND1(SYNDDS_PP_EXPAND1(__VA_ARGS__))))
#define SYNDDS_PP_EXPAND1(...) __VA_ARGS__
#define SYNDDS_PP_FOR_EACH(M, C, ...) \
  __VA_OPT__(SYNDDS_PP_EXPAND(SYNDDS_PP_FOR_EACH_STEP(M, C, __VA_ARGS__)))
#define SYNDDS_PP_FOR_EACH_STEP(M, C, A, ...) \
  M(C, A) __VA_OPT__(SYNDDS_PP_FOR_EACH_AGAIN SYNDDS_PP_PARENS(M, C, __VA_ARGS__))
#define SYNDDS_PP_FOR_EACH_AGAIN() SYNDDS_PP_FOR_EACH_STEP

// SYNDDS_PP_IS_PAREN(x) is 1 for "(a, b)", 0 for a plain name.
#define SYNDDS_PP_CAT(a, b) SYNDDS_PP_CAT_(a, b)
#define SYNDDS_PP_CAT_(a, b) a##b
#define SYNDDS_PP_IS_PAREN(x) SYNDDS_PP_IS_PAREN_CHECK(SYNDDS_PP_IS_PAREN_PROBE x)
#define SYNDDS_PP_IS_PAREN_PROBE(...) ~, 1
#define SYNDDS_PP_IS_PAREN_CHECK(...) SYNDDS_PP_IS_PAREN_SECOND(__VA_ARGS__, 0, ~)
#define SYNDDS_PP_IS_PAREN_SECOND(a, b, ...) b
#define SYNDDS_PP_UNPAREN(...) __VA_ARGS__
#define SYNDDS_PP_APPLY(M, ...) M(__VA_ARGS__)

#define SYNDDS_FIELD_VISIT_(MSG, E) \
  SYNDDS_PP_CAT(SYNDDS_FIELD_VISIT_, SYNDDS_PP_IS_PAREN(E))(MSG, E)
#define SYNDDS_FIELD_VISIT_0(MSG, NAME) SYNDDS_FIELD_VISIT_AS(MSG, NAME, NAME)
#define SYNDDS_FIELD_VISIT_1(MSG, PAIR) \
  SYNDDS_PP_APPLY(SYNDDS_FIELD_VISIT_AS, MSG, SYNDDS_PP_UNPAREN PAIR)
#define SYNDDS_FIELD_VISIT_AS(MSG, NAME, WIRE)                                      \
  f(#NAME, &MSG::NAME, [](auto& x) -> decltype(auto) { return x.WIRE(); });
#define SYNDDS_FIELD_COUNT_(MSG, E) +1

/// The field list of MSG (in namespace syndds::proto, after the struct): every member, in
/// declaration order, each a name or (plain_name, idl_name).
#define SYNDDS_FIELDS(MSG, ...)                                                 \
  template <>                                                                   \
  struct Fields<MSG> {                                                          \
    static constexpr std::size_t count =                                        \
        0 SYNDDS_PP_FOR_EACH(SYNDDS_FIELD_COUNT_, MSG, __VA_ARGS__);            \
    template <typename F>                                                       \
    static constexpr void visit(F& f) {                                         \
      SYNDDS_PP_FOR_EACH(SYNDDS_FIELD_VISIT_, MSG, __VA_ARGS__)                 \
    }                                                                           \
  };

}  // namespace syndds::proto

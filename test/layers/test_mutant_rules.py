"""The mutation rules of tools/mutant_rules.py (issue 37): each rule applied to a small C++ text
written here gives the expected lines, comments, strings and preprocessor lines are never
mutated, and the same seed draws the same sample. Run by the pytest layers target."""
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "tools"))

import mutant_rules as mr  # noqa: E402


def afters(text, rule):
    return [m.after for m in mr.mutations_of_text("a.cpp", text, rules=(rule,))]


def test_arithmetic_binary_operators_only():
    text = "double f(double a, double* p) {\n  const double x = a + b * -c / *p - d;\n}\n"
    assert afters(text, "arithmetic") == [
        "  const double x = a - b * -c / *p - d;",
        "  const double x = a + b / -c / *p - d;",
        "  const double x = a + b * -c * *p - d;",
        "  const double x = a + b * -c / *p + d;",
    ]


def test_arithmetic_compound_assignment_and_increments_untouched():
    assert afters("  sum += w;\n  ++i;\n  j--;\n", "arithmetic") == ["  sum -= w;"]


def test_arithmetic_skips_string_concatenation():
    assert afters('  s = "x: " + name + " deg";\n  t = u + v;\n', "arithmetic") == ["  t = u - v;"]


def test_comparison_each_operator():
    text = "  if (a < b && c >= d) x = e == f;\n  y = g != h || i > j || k <= l;\n"
    assert afters(text, "comparison") == [
        "  if (a <= b && c >= d) x = e == f;",
        "  if (a < b && c > d) x = e == f;",
        "  if (a < b && c >= d) x = e != f;",
        "  y = g == h || i > j || k <= l;",
        "  y = g != h || i >= j || k <= l;",
        "  y = g != h || i > j || k < l;",
    ]


def test_comparison_leaves_templates_streams_and_arrows():
    text = ("  std::vector<double> v;\n  std::cout << x >> y;\n  auto f = [](int a) -> int {"
            " return a; };\n  template <typename T> int g();\n")
    assert afters(text, "comparison") == []


def test_constant_times_two_and_half():
    assert afters("  const double h = 1e-3 * sigma + 0.25f + 0.0;\n", "constant") == [
        "  const double h = 0.002 * sigma + 0.25f + 0.0;",
        "  const double h = 0.0005 * sigma + 0.25f + 0.0;",
        "  const double h = 1e-3 * sigma + 0.5f + 0.0;",
        "  const double h = 1e-3 * sigma + 0.125f + 0.0;",
    ]


def test_integer_plus_and_minus_one_not_in_floats_names_or_hex():
    text = "  for (int i = 0; i < 3u; ++i) x2[i] = 1e-6 + 0x10 + 2.5;\n"
    assert afters(text, "integer") == [
        "  for (int i = 1; i < 3u; ++i) x2[i] = 1e-6 + 0x10 + 2.5;",
        "  for (int i = -1; i < 3u; ++i) x2[i] = 1e-6 + 0x10 + 2.5;",
        "  for (int i = 0; i < 4u; ++i) x2[i] = 1e-6 + 0x10 + 2.5;",
        "  for (int i = 0; i < 2u; ++i) x2[i] = 1e-6 + 0x10 + 2.5;",
    ]


def test_swap_adjacent_name_arguments_of_a_call_not_a_declaration():
    text = ("  f(a, b.c, 3);\n  void g(double a, double b);\n  if (x, y) z();\n"
            "  h(k(p), q, r);\n")
    assert afters(text, "swap") == ["  f(b.c, a, 3);", "  h(k(p), r, q);"]


def test_negate_if_and_while_with_the_condition_on_the_line():
    text = '  if (n > 0 && s == "a") f();\n  while (ok(x)) {\n  if (a &&\n      b) g();\n'
    assert afters(text, "negate") == ['  if (!(n > 0 && s == "a")) f();', "  while (!(ok(x))) {"]


def test_remove_expression_statements_only():
    text = ("void f() {\n  x = 1;\n  double y = 2;\n  g(x);\n  return;\n  if (c)\n    h();\n"
            "  obj.k(1,\n        2);\n  ++n;\n  p->q = r;\n  a == b;\n}\n")
    removed = [m.line for m in mr.mutations_of_text("a.cpp", text, rules=("remove",))]
    assert removed == [2, 4, 10, 11]
    assert all(m.after == "" for m in mr.mutations_of_text("a.cpp", text, rules=("remove",)))


def test_comments_strings_and_preprocessor_lines_never_mutated():
    text = ('#include "a/b.h"\n#define TWICE(x) (2 * (x) + 1)\n// a + b < 3.0\n'
            '/* if (x) y = 1;\n   z = 2 * w; */\nconst char* s = "a + b < 1.5, f(u, v)";\n'
            "#if 0\n  q = r + 1;\n#endif\nchar c = '+';\n")
    assert mr.mutations_of_text("a.cpp", text) == []


def test_code_after_if_0_block_and_in_else_of_if_0_is_mutated():
    text = "#if 0\nx = a + b;\n#if 1\ny = 1;\n#endif\n#else\nz = c + d;\n#endif\nw = e - f;\n"
    lines = sorted({m.line for m in mr.mutations_of_text("a.cpp", text, ("arithmetic",))})
    assert lines == [7, 9]


def test_raw_string_is_not_mutated():
    text = 'auto s = R"(a + b; if (x) y = 1;)";\nint k = 1 + 2;\n'
    assert {m.line for m in mr.mutations_of_text("a.cpp", text)} == {2}


def test_brace_only_lines_are_not_candidates():
    assert list(mr.compiled_lines("{\n  };\n}\nx = 1;\n")) == [4]


def test_apply_changes_only_the_line_and_refuses_a_changed_file():
    text = "a = 1;\nb = c + d;\n"
    (m,) = mr.mutations_of_text("a.cpp", text, rules=("arithmetic",))
    assert m.apply(text) == "a = 1;\nb = c - d;\n"
    try:
        m.apply("a = 1;\nb = c * d;\n")
        raise AssertionError("applied to a changed line")
    except ValueError:
        pass


def pool():
    text = "".join("  x%d = a + %d * b;\n  if (x%d < 2.5) f(p, q);\n" % (i, i, i)
                   for i in range(30))
    return mr.mutations_of_text("a.cpp", text)


def test_same_seed_same_sample_other_seed_other_sample():
    a = [(m.line, m.rule, m.after) for m in mr.draw(pool(), 10, seed=1)]
    b = [(m.line, m.rule, m.after) for m in mr.draw(list(reversed(pool())), 10, seed=1)]
    c = [(m.line, m.rule, m.after) for m in mr.draw(pool(), 10, seed=2)]
    assert a == b
    assert a != c
    assert len(set(a)) == 10


def test_every_rule_is_in_the_pool_and_keys_are_stable():
    rules = {m.rule for m in pool()}
    assert rules == {"arithmetic", "comparison", "constant", "integer", "swap", "negate", "remove"}
    keys = [m.key() for m in pool()]
    assert keys == [m.key() for m in pool()] and len(set(keys)) == len(keys)

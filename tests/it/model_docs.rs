//! The complete example of docs/model-language.md parses and gives the equation the page shows.

#[test]
fn the_documented_example_gives_the_documented_equation() {
    let page = std::fs::read_to_string("docs/model-language.md").expect("docs page");
    let start = page.find("```text\n").expect("an example block") + "```text\n".len();
    let len = page[start..].find("```").expect("closed block");
    let model = harmonid::model::parse_str(&page[start..start + len], "docs example")
        .unwrap_or_else(|e| panic!("{}", e.render_plain(100)));
    let shown = "q1'' + (w1/Q1) q1' + w1^2 q1 + beta1 q1^3 + eta q1^2 q2 + g12 q1 q2^2 + mu q1 q2 q3 + g13 q1 q3^2 = F1(t)";
    assert!(page.contains(shown));
    assert_eq!(model.equation_text(0), shown);
    assert_eq!(model.params.len(), 9);
}

#[test]
fn the_documented_velocity_example_gives_velocity_terms() {
    let page = std::fs::read_to_string("docs/model-language.md").expect("docs page");
    let section = page.find("## Velocities").expect("the velocity section");
    let start = section + page[section..].find("```text\n").expect("its example") + 8;
    let len = page[start..].find("```").expect("closed block");
    let model = harmonid::model::parse_str(&page[start..start + len], "velocity example")
        .unwrap_or_else(|e| panic!("{}", e.render_plain(100)));
    assert!(model.has_velocity_terms());
    let q1 = model.equation_text(0);
    assert!(
        q1.contains("(eta + 1/2*c) q1^2 d(q1)") && q1.contains("eta12 q2^2 d(q1)"),
        "{q1}"
    );
    assert!(
        model.equation_text(1).contains("- mu d(q2)"),
        "{}",
        model.equation_text(1)
    );
    assert!(
        model.equation_text(4).contains("eta5 q5^2 d(q5)"),
        "{}",
        model.equation_text(4)
    );
    let json = model.to_json();
    assert!(
        json.contains("\"q1^2*d(q1)\": {\"eta\": 1.0, \"c\": 0.5}"),
        "{json}"
    );
}

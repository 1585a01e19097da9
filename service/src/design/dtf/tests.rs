use super::*;

#[test]
fn print_example() {
    let e = example_3_41().unwrap();
    println!("{}", e.report());
}

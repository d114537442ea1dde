use ecr_macros::ecr_method;

ecr_method!(r = 2, family = "tc");

fn main() {}

use ecr_macros::ecr_method;

ecr_method!(r = 2.5);

fn main() {}

use ecr_macros::ecr_method;

ecr_method!(r = 0);

fn main() {}

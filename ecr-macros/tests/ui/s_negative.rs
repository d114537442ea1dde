use ecr_macros::ecr_method;

ecr_method!(r = 2, s = -3);

fn main() {}

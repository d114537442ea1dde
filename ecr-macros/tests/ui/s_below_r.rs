use ecr_macros::ecr_method;

ecr_method!(r = 3, s = 2);

fn main() {}
